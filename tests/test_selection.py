"""Selecting the policy a game run hands over from its learned reward (rankgame.game.selection)."""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS

from rankgame.cli import main
from rankgame.evaluate import EvaluateConfig, evaluate_policy
from rankgame.game.selection import (
    SELECTED_POLICY_NAME,
    SELECTION_COLUMN,
    PolicySelection,
    learned_return_ratio,
    selected_evaluation,
)
from rankgame.policy.io import load_policy

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import selection as selection_benchmark  # noqa: E402


def test_the_ratio_is_the_policys_learned_return_over_the_experts_and_undefined_without_a_positive_expert() -> None:
    assert learned_return_ratio(0.5, 2.0) == 0.25
    assert learned_return_ratio(1.0, 3.0) == 0.333333  # the 6 digits metrics.csv keeps
    for policy, expert in [(1.0, 0.0), (1.0, -2.0), (math.nan, 1.0), (1.0, math.inf)]:
        assert math.isnan(learned_return_ratio(policy, expert))


def test_the_selection_keeps_the_latest_of_the_largest_and_forgets_at_a_switch() -> None:
    selection = PolicySelection()
    assert [selection.improves(r) for r in [math.nan, 0.2, 0.5, 0.4, 0.5, math.nan]] == [
        False,
        True,
        True,
        False,
        True,
        False,
    ]
    assert selection.best == 0.5
    selection.reset()
    assert selection.best is None and selection.improves(0.1)


def _write_metrics(path: Path, rows: list[tuple[int, str, float]]) -> Path:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["env_steps", SELECTION_COLUMN, "normalized_score"])
        writer.writerows(rows)
    return path


def test_the_selected_evaluation_is_read_back_from_metrics(tmp_path: Path) -> None:
    rows = [(1000, "0.1", -50.0), (2000, "0.9", 95.0), (3000, "", 10.0), (4000, "0.9", 90.0), (5000, "0.3", 20.0)]
    _write_metrics(tmp_path / "metrics.csv", rows)
    selected = selected_evaluation(tmp_path)
    assert selected is not None
    assert (selected.env_steps, selected.learned_return, selected.normalized_score) == (4000, 0.9, 90.0)
    after_switch = selected_evaluation(tmp_path, since=4000)
    assert after_switch is not None and after_switch.env_steps == 5000
    for name, text in [("undefined", None), ("old", "env_steps,normalized_score\n1000,3.0\n")]:
        (tmp_path / name).mkdir()
        if text is None:
            _write_metrics(tmp_path / name / "metrics.csv", [(1000, "", 3.0)])
        else:
            (tmp_path / name / "metrics.csv").write_text(text)
        assert selected_evaluation(tmp_path / name) is None


def test_a_toy_run_hands_over_the_policy_its_learned_reward_rates_best(
    toy_expert_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    args = [*TOY_TRAIN_ARGS, "--method", "rank-pal-auto", "--expert", str(toy_expert_file), "--steps", "2000"]
    capsys.readouterr()
    assert main(["train", *args, "--eval-every", "400", "--eval-episodes", "5", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)["selected_policy"]
    with (out / "metrics.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    ratios = [float(row[SELECTION_COLUMN]) for row in rows]
    assert summary["learned_return"] == max(ratios) and summary["path"] == str(out / SELECTED_POLICY_NAME)
    saved = load_policy(out / SELECTED_POLICY_NAME)
    assert saved.metadata["env_steps"] == summary["env_steps"]
    # The untrained policy scores about -100 and the first evaluation comes before any policy update;
    # the policy chosen without the true reward is one that imitates, on episodes it was not chosen on.
    assert float(rows[0]["normalized_score"]) < 0.0 < summary["normalized_score"]
    fresh = evaluate_policy(
        EvaluateConfig(policy=out / SELECTED_POLICY_NAME, episodes=10, seed=777, expert=toy_expert_file)
    )
    assert fresh["normalized_score"] > 50.0, (fresh, rows)

    # The benchmark scores both actors on fresh episodes, the selected one exactly as evaluate does.
    report = tmp_path / "fresh.json"
    figure = tmp_path / "selection.png"
    args = [str(out), "--episodes", "10", "--seed", "777", "--out", str(report), "--plot", str(figure)]
    assert selection_benchmark.main(args) == 0
    assert figure.read_bytes()[:4] == b"\x89PNG"
    result = json.loads(report.read_text())
    assert result["runs"][0]["selected"]["fresh_score"] == fresh["normalized_score"]
    assert result["runs"][0]["selected"]["env_steps"] == summary["env_steps"]
    assert result["aggregate"]["n"] == 1 and result["aggregate"]["selected"]["below"] == 0
    assert selection_benchmark.main([str(tmp_path / "missing")]) == 1


def test_spearman_ranks_with_ties_averaged() -> None:
    assert selection_benchmark.spearman(np.array([1.0, 2.0, 3.0]), np.array([10.0, 30.0, 20.0])) == pytest.approx(0.5)
    # x ranks 0, 1.5, 1.5, 3 against y ranks 0, 1, 2, 3: correlation 0.9486833 (= 3 / sqrt(10))
    value = selection_benchmark.spearman(np.array([1.0, 2.0, 2.0, 4.0]), np.arange(4.0))
    assert value == pytest.approx(3 / np.sqrt(10))
