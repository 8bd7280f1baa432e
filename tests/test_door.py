"""The Door task (rankgame/Door-v0): robosuite's Door with a Panda arm as a Gymnasium task."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import assert_missing_package_is_one_line_error

from rankgame.envs.make import env_spec, make_env
from rankgame.envs.manipulation import DOOR_ID

pytest.importorskip("robosuite")  # part of the test extra; this guards partial installs


@pytest.fixture(scope="module")
def door():
    env = make_env(DOOR_ID)
    yield env
    env.close()


def test_door_has_the_panda_spaces_and_a_200_step_horizon(door) -> None:
    spec = env_spec(door)
    assert (spec.obs_dim, spec.act_dim, spec.max_episode_steps) == (57, 7, 200)
    assert np.all(spec.act_low == -1.0) and np.all(spec.act_high == 1.0)


def test_equal_seeds_give_equal_starts_and_tasks_do_not_share_a_stream(door) -> None:
    first, _ = door.reset(seed=3)
    following, _ = door.reset()
    other = make_env(DOOR_ID)
    other.reset(seed=9)  # draws from its own stream, not from door's
    other.close()
    global_state = np.random.get_state()[1].copy()
    assert np.array_equal(door.reset(seed=3)[0], first)
    assert np.array_equal(door.reset()[0], following)
    assert not np.array_equal(first, following)  # the door and the arm start elsewhere
    assert np.array_equal(np.random.get_state()[1], global_state)  # NumPy's global stream untouched


def test_an_episode_runs_the_full_horizon_and_reports_success(door) -> None:
    door.reset(seed=0)
    door.action_space.seed(0)
    steps, terminated, truncated, rewards = 0, False, False, []
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = door.step(door.action_space.sample())
        steps += 1
        rewards.append(reward)
        assert info["success"] is False  # random arm motions do not open the door
    assert (steps, terminated, truncated) == (200, False, True)
    assert np.all(np.isfinite(obs)) and min(rewards) >= 0.0 and max(rewards) <= 1.0  # shaped reward


def test_without_robosuite_the_error_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert_missing_package_is_one_line_error(
        monkeypatch, capsys, tmp_path / "run", DOOR_ID, "robosuite", "door", "robosuite"
    )
