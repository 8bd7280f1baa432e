"""The Pen task (rankgame/Pen-v0): the paper's pen-v0 episode rules on Gymnasium-Robotics' Adroit pen."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import assert_missing_package_is_one_line_error

from rankgame.envs.make import env_spec, make_env
from rankgame.envs.manipulation import PEN_DROP_HEIGHT, PEN_HEIGHT_INDEX, PEN_ID

pytest.importorskip("gymnasium_robotics")  # part of the test extra; this guards partial installs


def test_pen_has_the_adroit_spaces_and_pen_v0_horizon() -> None:
    env = make_env(PEN_ID)
    spec = env_spec(env)
    assert (spec.obs_dim, spec.act_dim, spec.max_episode_steps) == (45, 24, 100)
    obs, _ = env.reset(seed=0)
    assert obs[PEN_HEIGHT_INDEX] > PEN_DROP_HEIGHT  # the pen starts in the hand
    env.close()


def test_an_episode_ends_when_the_pen_falls_and_not_before() -> None:
    env = make_env(PEN_ID)
    env.reset(seed=0)
    env.action_space.seed(0)
    heights, terminated, truncated = [], False, False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(env.action_space.sample())
        heights.append(obs[PEN_HEIGHT_INDEX])
        assert "success" in info
    # Random hand motions drop the pen well within the 100 steps (38-71 steps over seeds 0-9).
    assert terminated and not truncated and len(heights) < 100
    assert heights[-1] < PEN_DROP_HEIGHT and np.all(np.asarray(heights[:-1]) >= PEN_DROP_HEIGHT)
    env.close()


def test_without_gymnasium_robotics_the_error_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert_missing_package_is_one_line_error(
        monkeypatch, capsys, tmp_path / "run", PEN_ID, "gymnasium_robotics", "manipulation", "Gymnasium-Robotics"
    )


def test_pen_evaluations_report_a_success_rate(tmp_path: Path) -> None:
    from rankgame.envs.rollout import run_episodes, success_rate

    env = make_env(PEN_ID)
    env.action_space.seed(0)
    _, success_steps = run_episodes(env, lambda obs: env.action_space.sample(), 2, seed=0)
    assert all(isinstance(steps, int) for steps in success_steps)
    assert success_rate(success_steps) in (0.0, 0.5, 1.0)
    env.close()
