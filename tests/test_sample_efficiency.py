"""The sample-efficiency benchmark's summary (benchmarks/sample_efficiency.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from sample_efficiency import summarize, window_mean  # noqa: E402


def test_window_mean_averages_the_evaluations_up_to_the_step() -> None:
    scores = {10_000: 1.0, 20_000: 3.0, 30_000: 8.0, 40_000: 100.0}
    assert window_mean(scores, 30_000, 20_000) == 5.5  # 20k and 30k; 10k lies on the open end
    assert window_mean(scores, 30_000, 10_000) == 8.0


def test_summary_gives_the_point_and_the_window_over_seeds() -> None:
    args = argparse.Namespace(
        envs=["Hopper-v5"], methods=["rank-pal-auto"], seeds=[0, 1, 2], at=[100_000], window=20_000
    )
    all_scores = {
        ("Hopper-v5", "rank-pal-auto", 0): {80_000: 0.0, 90_000: 20.0, 100_000: 40.0},
        ("Hopper-v5", "rank-pal-auto", 1): {80_000: 0.0, 90_000: 60.0, 100_000: 80.0},
        ("Hopper-v5", "rank-pal-auto", 2): {90_000: 50.0},  # not yet at 100k: left out
    }
    (row,) = summarize(args, all_scores)
    assert (row["seeds"], row["mean"], row["std"]) == (2, 60.0, 20.0)
    assert (row["window_mean"], row["window_std"]) == (50.0, 20.0)  # seeds' windows: 30 and 70
    assert row["published"] == 86
