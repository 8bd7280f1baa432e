"""The ablation runner (benchmarks/ablations.py): every variant is a valid `rankgame train`, and the summary."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from ablations import ABLATIONS, ablation_jobs, summarize  # noqa: E402

from rankgame.cli import train_config_from_argv  # noqa: E402


@pytest.mark.parametrize("name", list(ABLATIONS))
def test_every_variant_is_a_valid_training_command(name: str, tmp_path: Path) -> None:
    jobs = ablation_jobs(name, ["Hopper-v5"], [0], tmp_path / "runs", tmp_path / "archive")
    assert len(jobs) == len(ABLATIONS[name].variants)
    labels = [variant.label for variant, _ in jobs]
    assert len(set(labels)) == len(labels)
    for variant, job in jobs:
        argv = job.command(1000)[4:]  # after `python -m rankgame.cli train`
        cfg, _ = train_config_from_argv(argv)
        cfg.validate()
        assert cfg.method == variant.method and cfg.out == job.out


def test_summary_is_the_mean_and_deviation_over_seeds(tmp_path: Path) -> None:
    jobs = ablation_jobs("rankings", ["Hopper-v5"], [0, 1], tmp_path / "runs", tmp_path / "archive")
    scores = {("auto", 0): (10.0, 30.0), ("auto", 1): (20.0, 50.0), ("vanilla", 0): (5.0, 7.0)}
    for variant, job in jobs:
        if (variant.label, job.seed) in scores:
            job.archived.mkdir(parents=True)
            first, second = scores[variant.label, job.seed]
            rows = f"env_steps,normalized_score\n1000,{first}\n2000,{second}\n"
            (job.archived / "metrics.csv").write_text(rows)
    rows = {(r["variant"], r["step"]): r for r in summarize(jobs, [2000])}
    assert (rows["auto", 2000]["mean"], rows["auto", 2000]["std"], rows["auto", 2000]["seeds"]) == (40.0, 10.0, 2)
    assert (rows["vanilla", 2000]["mean"], rows["vanilla", 2000]["seeds"]) == (7.0, 1)
