"""Learned reward landscapes in 2-D (benchmarks/reward_landscape.py): its measures on rewards worked out
by hand, and a short fit where the ranking game's reward rises from the agent and GAIL's does not."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import reward_landscape  # noqa: E402

# Agent states on y = -1 below expert states on y = 1: every segment is vertical and 2 long.
X = np.linspace(-1.0, 1.0, 5)
AGENT = np.stack([X, np.full(5, -1.0)], axis=-1)[None]
EXPERT = np.stack([X, np.full(5, 1.0)], axis=-1)[None]


def test_a_straight_ramp_rises_evenly() -> None:
    # r = (y + 1) / 2: 0 at the agent, 1 at the expert, |grad r| = 1/2 everywhere, times D = 2.
    metrics, profile, grid = reward_landscape.measure(lambda s: (s[..., 1] + 1) / 2, EXPERT, AGENT)
    np.testing.assert_allclose(profile, reward_landscape.PATH, atol=1e-12)
    assert metrics["slope_at_agent"] == pytest.approx(1.0)
    assert metrics["steepest_tenth"] == pytest.approx(0.1)
    assert metrics["gradient_p95"] == pytest.approx(1.0)
    assert grid.shape == (reward_landscape.GRID, reward_landscape.GRID)


def test_a_step_near_the_expert_is_flat_at_the_agent_and_steep_once() -> None:
    # r = 1 for y > 0.5, else 0: the whole rise between u = 0.7 and 0.8 of the way, none near the agent.
    metrics, _, _ = reward_landscape.measure(lambda s: (s[..., 1] > 0.5).astype(float), EXPERT, AGENT)
    assert metrics["slope_at_agent"] == 0.0
    assert metrics["steepest_tenth"] == 1.0
    # Central differences over a grid step h = 5 / 100 see a jump of 1 over 2h: |grad r| D = 2 / 0.1 = 20,
    # on two grid rows of 101, under the 95th percentile; everywhere else the gradient is 0.
    assert metrics["gradient_p95"] == pytest.approx(0.0, abs=1e-9)


def test_the_ranking_games_reward_rises_from_the_agent_and_gails_does_not(capsys: pytest.CaptureFixture[str]) -> None:
    assert reward_landscape.main(["--steps", "240", "--seeds", "0"]) == 0
    methods = json.loads(capsys.readouterr().out)["methods"]
    auto, gail = (methods[label]["summary"] for label in ("rank-game (auto)", "GAIL"))
    # The auto targets put 29% of the rise in the first fifth of the way (exp schedule, beta = -1): a
    # slope near 1.4 at the agent, where the discriminator's reward has saturated at 0.
    assert auto["slope_at_agent"]["mean"] > 1.0 and gail["slope_at_agent"]["mean"] < 0.1
    assert gail["gradient_p95"]["mean"] > auto["gradient_p95"]["mean"]
    assert methods["rank-game (auto)"]["summary"]["slope_at_agent"]["n"] == 1


def test_settings_that_make_no_sense_are_one_line_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert reward_landscape.main(["--horizon", "1"]) == 1
    assert capsys.readouterr().err == "reward_landscape.py: --horizon must be at least 2\n"
