"""Collapses after first reaching expert level (benchmarks/stability.py), by hand."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from stability import SAC_TRUE_REWARD, collapse_counts, read_run, summarize  # noqa: E402


def test_only_evaluations_after_the_first_one_at_the_threshold_count() -> None:
    # Reaches 80 at the third evaluation; of the four after it, 31 and 49.9 are collapses, 50 is not.
    assert collapse_counts((10.0, 40.0, 85.0, 31.0, 90.0, 50.0, 49.9), reach=80.0, below=50.0) == (4, 2)
    assert collapse_counts((10.0, 79.9, 20.0), reach=80.0, below=50.0) is None  # never reached
    assert collapse_counts((95.0,), reach=80.0, below=50.0) == (0, 0)


def _run(folder: Path, config: dict, header: str, rows: list[str]) -> Path:
    folder.mkdir(parents=True)
    (folder / "config.json").write_text(json.dumps(config))
    (folder / "metrics.csv").write_text("\n".join([header, *rows]) + "\n")
    return folder


def test_groups_share_final_and_best_and_the_sac_reference(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    game = {"env": "Hopper-v5", "method": "rank-pal-auto"}
    header = "env_steps,eval_return,normalized_score"
    a = _run(root / "a", game, header, ["1,1,90", "2,1,30", "3,1,95"])  # 2 later, 1 collapse
    b = _run(root / "b", game, header, ["1,1,20", "2,1,85", "3,1,88", "4,1,40", "5,1,45"])  # 3 later, 2
    c = _run(root / "c", game, header, ["1,1,10", "2,1,60"])  # never reaches 80
    runs = [read_run(folder, root) for folder in (a, b, c)]
    (row,) = summarize([r for r in runs if r is not None], reach=80.0, below=50.0)
    assert (row["runs"], row["reached"], row["after"], row["collapsed"]) == (3, 2, 5, 3)
    assert row["share"] == pytest.approx(3 / 5)
    assert row["final"] == pytest.approx((95 + 45 + 60) / 3) and row["best"] == pytest.approx((95 + 88 + 60) / 3)
    # A rankgame expert run is normalized with the shipped expert data: its expert return scores 100.
    from rankgame.data.experts import load_shipped_expert

    expert = load_shipped_expert("Hopper-v5")
    top, bottom = float(expert.returns.mean()), float(expert.metadata["random_return_mean"])
    sac = _run(
        root / "sac", {"env": "Hopper-v5"}, "env_steps,train_return,eval_return", [f"1,0,{bottom}", f"2,0,{top}"]
    )
    reference = read_run(sac, root)
    assert reference is not None and reference.group == ("runs", "Hopper-v5", SAC_TRUE_REWARD)
    assert reference.scores == pytest.approx((0.0, 100.0))
