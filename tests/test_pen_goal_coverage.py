"""The Pen goal-coverage analysis (benchmarks/pen_goal_coverage.py): its grouping, by hand."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from pen_goal_coverage import group_by_cosine, nearest_cosine, unit_goals  # noqa: E402


def test_goals_are_read_from_entries_36_to_38_and_scaled_to_unit_length() -> None:
    obs = np.zeros((1, 45))
    obs[0, 36:39] = [0.0, 3.0, 4.0]
    np.testing.assert_allclose(unit_goals(obs), [[0.0, 0.6, 0.8]])


def test_each_goal_is_compared_with_its_nearest_demonstrated_goal() -> None:
    demonstrated = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    goals = np.array([[0.6, 0.8, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
    np.testing.assert_allclose(nearest_cosine(goals, demonstrated), [0.8, 0.0, 0.0])


def test_groups_hold_their_episodes_and_leave_empty_ones_out() -> None:
    cosines = np.array([0.99, 1.0, 0.9, 0.2])
    returns = np.array([4000.0, 3000.0, 10.0, -20.0])
    successes = np.array([1.0, 0.0, 0.0, 0.0])
    groups = group_by_cosine(cosines, returns, successes)
    assert [(g["cosine_from"], g["cosine_to"], g["episodes"]) for g in groups] == [
        (-1.0, 0.5, 1),
        (0.8, 0.95, 1),
        (0.95, 1.0, 2),  # a cosine of exactly 1 belongs to the last group
    ]
    assert groups[2]["success_rate"] == pytest.approx(0.5)
    assert groups[2]["mean_return"] == pytest.approx(3500.0)
