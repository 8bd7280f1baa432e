"""benchmarks/collapse_probe.py: the probe's rows on a tiny game, its figure and its refusals."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from collapse_probe import PROBE_COLUMNS, main  # noqa: E402


def test_probe_rows_follow_the_evaluations_and_the_plot_is_written(tmp_path: Path, toy_expert_file: Path) -> None:
    out = tmp_path / "run"
    argv = [*TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--steps", "1000", "--eval-every", "500"]
    assert main([*argv, "--out", str(out)]) == 0
    with (out / "probe.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    metrics = list(csv.DictReader((out / "metrics.csv").open()))
    assert [r["env_steps"] for r in rows] == ["500", "1000"] == [r["env_steps"] for r in metrics]
    assert set(rows[0]) == set(PROBE_COLUMNS)
    for row, logged in zip(rows, metrics, strict=True):
        values = {name: float(row[name]) for name in PROBE_COLUMNS}
        assert all(np.isfinite(list(values.values())))
        assert values["normalized_score"] == pytest.approx(float(logged["normalized_score"]), rel=1e-5)
        for name in ("reward_expert", "reward_policy", "reward_stand", "reward_absorbing"):
            assert -10.0 <= values[name] <= 10.0  # rewards are bounded to [-r_max, r_max], r_max = 10
        # gamma = 0.99: standing for ever is worth 100 steps of its reward.
        assert values["stand_forever"] == pytest.approx(100.0 * values["reward_stand"], rel=1e-4)
        assert values["expert_forever"] == pytest.approx(100.0 * values["reward_expert"], rel=1e-4)
        assert 1 <= values["policy_length"] <= 40  # the toy task's horizon
    figure = tmp_path / "probe.png"
    assert main(["--plot", str(figure), "--probe", str(out / "probe.csv")]) == 0
    assert figure.read_bytes()[:4] == b"\x89PNG"


def test_methods_without_a_sac_game_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*TOY_TRAIN_ARGS, "--method", "bc", "--out", str(tmp_path / "bc")]) == 1
    assert "only games with the SAC policy player" in capsys.readouterr().err
    assert not (tmp_path / "bc").exists()
    assert main(["--plot", str(tmp_path / "x.png"), "--probe", str(tmp_path / "missing.csv")]) == 1


def test_the_summary_pairs_each_evaluation_after_reaching_80_with_the_reward_before_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Scores 40, 85, 30 (a collapse), 90, 95, 20 (a collapse): the evaluation at 30k follows 85 (stand /
    # policy = 6 / 4) and its probe episode lasts 1000 steps at the healthy bonus (a stand); 40k follows
    # a collapse and is left out; 50k follows 90 (2 / 8); 60k follows 95 (1 / 1) and its probe episode
    # ends after 300 steps (a fall). The learned reward of the absorbing state is 0 and the expert's 2, so
    # the learned return ratio (r_policy L + 0) / (2 H) is largest, 8 / 2, at 40k: the selected policy
    # (at 60k it is 1 x 300 / 2000: the fall is paid the absorbing state's 0 for the rest).
    path = tmp_path / "probe.csv"
    scores, stand, policy = [40, 85, 30, 90, 95, 20], [1, 6, 1, 2, 1, 1], [1, 4, 1, 8, 1, 1]
    lengths, per_step = [1000, 1000, 1000, 1000, 1000, 300], [3.0, 3.0, 1.0, 3.0, 3.0, 2.5]
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(PROBE_COLUMNS)
        for i, score in enumerate(scores):
            values = dict.fromkeys(PROBE_COLUMNS, 0.0)
            values.update(
                env_steps=10000 * (i + 1),
                normalized_score=score,
                reward_stand=stand[i],
                reward_policy=policy[i],
                policy_length=lengths[i],
                policy_true_per_step=per_step[i],
                reward_expert=2.0,
            )
            writer.writerow([values[name] for name in PROBE_COLUMNS])
    assert main(["--summary", str(path)]) == 0
    (summary,) = json.loads(capsys.readouterr().out)
    assert summary["collapses"] == 2 and summary["others"] == 1
    assert summary["stand_over_policy_before_collapses"] == [1.5, 1.0]
    assert summary["stand_over_policy_before_others"] == [0.25]
    assert summary["collapse_kinds"] == {"stand": 1, "fall": 1, "other": 0}
    assert [r["env_steps"] for r in summary["rows"]] == [30000, 50000, 60000]
    assert summary["final_score"] == 20.0
    assert summary["selected"] == {"env_steps": 40000, "normalized_score": 90.0, "learned_return_ratio": 4.0}
    assert main(["--summary", str(tmp_path / "missing.csv")]) == 1
