"""The sample-efficiency benchmark's summary (benchmarks/sample_efficiency.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from sample_efficiency import (  # noqa: E402
    PUBLISHED,
    Job,
    archive_if_finished,
    run_jobs,
    run_profile,
    summarize,
    window_mean,
)


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
    # Sample standard deviation of 40 and 80: sqrt(((40 - 60)^2 + (80 - 60)^2) / (2 - 1)) = 28.28.
    assert (row["seeds"], row["mean"], row["std"]) == (2, 60.0, 28.3)
    assert (row["window_mean"], row["window_std"]) == (50.0, 28.3)  # seeds' windows: 30 and 70
    assert row["published"] == 86
    assert row["paper_2m"] == (87.14, 16.14)


def test_a_run_profile_reads_the_run_up_to_its_length() -> None:
    scores = {10_000: 10.0, 20_000: 90.0, 30_000: 20.0, 40_000: 100.0, 50_000: 0.0}
    profile = run_profile(scores, 40_000, threshold=80.0)
    assert profile == {
        "first_step_at_threshold": 20_000,
        "late_median": 90.0,  # 20k, 30k and 40k: the second half of 40k steps
        "late_min": 20.0,
        "late_max": 100.0,
        "curve_mean": 55.0,  # (10 + 90 + 20 + 100) / 4; the evaluation at 50k lies beyond the run's length
    }
    assert run_profile(scores, 60_000, threshold=80.0) is None  # not yet that long


def test_a_run_is_archived_only_once_it_reached_the_requested_steps(tmp_path: Path) -> None:
    out, archived = tmp_path / "run", tmp_path / "archive"
    out.mkdir()
    (out / "metrics.csv").write_text("env_steps,normalized_score\n10000,5.0\n")
    (out / "config.json").write_text("{}")
    archive_if_finished(out, archived, 20_000)
    assert not archived.exists()  # not evaluated at 20k yet: the run is still going or was killed
    (out / "metrics.csv").write_text("env_steps,normalized_score\n10000,5.0\n20000,7.5\n")
    archive_if_finished(out, archived, 30_000)
    assert not archived.exists()  # a finished 20k run asked to go on to 30k is continued, not archived
    archive_if_finished(out, archived, 20_000)
    assert (archived / "metrics.csv").read_text() == (out / "metrics.csv").read_text()
    assert (archived / "config.json").exists()


def test_finished_runs_are_archived_and_only_the_rest_go_to_the_sweep(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sample_efficiency

    done = Job(tmp_path / "runs" / "a", tmp_path / "archive" / "a", "Hopper-v5", "rank-pal-auto", 0)
    todo = Job(tmp_path / "runs" / "b", tmp_path / "archive" / "b", "Hopper-v5", "rank-pal-auto", 1, "--reward.lr 1e-4")
    done.out.mkdir(parents=True)
    (done.out / "metrics.csv").write_text("env_steps,normalized_score\n20000,7.5\n")
    (done.out / "config.json").write_text("{}")
    launched = []
    monkeypatch.setattr(
        sample_efficiency, "launch_trials", lambda trials, storage, cores: launched.append(trials) or []
    )
    run_jobs([done, todo], 20_000, tmp_path / "runs", cores=1)
    assert (done.archived / "metrics.csv").exists()
    [[trial]] = launched
    assert trial.name == str(todo.out) and trial.steps == 20_000
    assert trial.argv[-5:] == ("--out", str(todo.out.resolve()), "--no-progress", "--reward.lr", "1e-4")
    launched.clear()
    run_jobs([done], 20_000, tmp_path / "runs", cores=1)
    assert launched == []  # nothing left to run: Ray is not started


def test_the_variants_without_contact_forces_are_compared_with_their_tasks_published_curves() -> None:
    for curves in PUBLISHED.values():
        assert curves["rankgame/AntNoContact-v5"] == curves["Ant-v5"]
        assert curves["rankgame/HumanoidNoContact-v5"] == curves["Humanoid-v5"]
