"""The ablation runner (benchmarks/ablations.py): every variant is a valid `rankgame train`, and the summary."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from ablations import ABLATIONS, ablation_jobs, markdown_table, per_seed_table, plot_ablation, summarize  # noqa: E402

from rankgame.cli import train_config_from_argv  # noqa: E402


@pytest.mark.parametrize("name", list(ABLATIONS))
def test_every_variant_is_a_valid_training_command(name: str, tmp_path: Path) -> None:
    jobs = ablation_jobs(name, ["Hopper-v5"], [0], tmp_path / "runs", tmp_path / "archive")
    assert len(jobs) == len(ABLATIONS[name].variants)
    labels = [variant.label for variant, _ in jobs]
    assert len(set(labels)) == len(labels)
    for variant, job in jobs:
        cfg, _ = train_config_from_argv(job.train_argv(1000))
        cfg.validate()
        assert cfg.method == variant.method and cfg.out == job.out.resolve()
        assert job.command(1000)[:2] == ["rankgame", "train"] and "--resume" not in job.command(1000)


def test_summary_is_the_mean_and_deviation_over_seeds(tmp_path: Path) -> None:
    jobs = ablation_jobs("rankings", ["Hopper-v5"], [0, 1], tmp_path / "runs", tmp_path / "archive")
    scores = {("auto", 0): (10.0, 30.0), ("auto", 1): (20.0, 50.0), ("vanilla", 0): (5.0, 7.0)}
    for variant, job in jobs:
        if (variant.label, job.seed) in scores:
            job.archived.mkdir(parents=True)
            first, second = scores[variant.label, job.seed]
            rows = f"env_steps,normalized_score\n1000,{first}\n2000,{second}\n"
            (job.archived / "metrics.csv").write_text(rows)
    rows = {row["variant"]: row for row in summarize(jobs, [1000, 2000], steps=2000)}
    # Sample standard deviations (n - 1): 30 and 50 give sqrt(2 * 10^2 / 1) = 14.1; one seed has none.
    assert rows["auto"]["at"][1] == {"step": 2000, "seeds": 2, "mean": 40.0, "std": 14.1}
    assert rows["vanilla"]["at"][0] == {"step": 1000, "seeds": 1, "mean": 5.0, "std": None}
    # Each run's mean over its evaluations: auto 20 and 35, so 27.5 ± sqrt(2 * 7.5^2) = 10.6; vanilla 6.
    assert (rows["auto"]["curve_mean"], rows["auto"]["curve_std"], rows["auto"]["curve_seeds"]) == (27.5, 10.6, 2)
    assert (rows["vanilla"]["curve_mean"], rows["vanilla"]["curve_seeds"]) == (6.0, 1)
    # A run that has not reached --steps has no curve mean yet; evaluations past it are not counted.
    early = {row["variant"]: row for row in summarize(jobs, [1000], steps=1000)}
    assert early["auto"]["curve_mean"] == 15.0 and early["auto"]["curve_seeds"] == 2
    assert summarize(jobs, [1000], steps=3000)[0]["curve_seeds"] == 0
    table = markdown_table(list(rows.values()), [1000, 2000], 2000).splitlines()
    assert table[0] == "| env | variant | 1k | 2k | mean of the evaluations to 2k |"
    assert table[2] == "| Hopper-v5 | auto | 15.0 ± 7.1 (2) | 40.0 ± 14.1 (2) | 27.5 ± 10.6 (2) |"


def test_plot_draws_one_curve_per_variant_with_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("matplotlib")
    import rankgame.plot

    drawn = {}

    def fake_plot_groups(groups, out, column, **kwargs):  # noqa: ANN001, ANN003, ANN202
        drawn[out] = (groups, {"column": column, **kwargs})
        return out

    monkeypatch.setattr(rankgame.plot, "plot_groups", fake_plot_groups)
    jobs = ablation_jobs("rankings", ["Hopper-v5", "Ant-v5"], [0, 1], tmp_path / "runs", tmp_path / "archive")
    for variant, job in jobs:
        if job.env == "Hopper-v5" and (variant.label, job.seed) != ("vanilla", 1):
            folder = job.out if job.seed == 0 else job.archived  # a live run and an archived one
            folder.mkdir(parents=True)
            (folder / "metrics.csv").write_text("env_steps,normalized_score\n1000,1.0\n")
    figures = plot_ablation("rankings", jobs, 1000, tmp_path / "rankings.png")
    assert figures == [tmp_path / "rankings-Hopper-v5.png"]  # Ant-v5 has no run: no figure
    groups, kwargs = drawn[figures[0]]
    assert [label for label, _ in groups] == ["auto", "vanilla"]
    where = [[run.relative_to(tmp_path).parts[0] for run in runs] for _, runs in groups]
    assert where == [["runs", "archive"], ["runs"]]
    assert kwargs["max_steps"] == 1000 and kwargs["column"] == "normalized_score"
    [success_figure] = plot_ablation("rankings", jobs, 1000, tmp_path / "success.png", metric="success")
    assert drawn[success_figure][1]["column"] == "eval_success"


def test_variants_can_be_restricted_by_label(tmp_path: Path) -> None:
    jobs = ablation_jobs("loss", ["Hopper-v5"], [0, 1], tmp_path, tmp_path, ["imit-ral", "rank-pal"])
    assert [(variant.label, job.seed) for variant, job in jobs] == [
        ("rank-pal", 0),
        ("rank-pal", 1),
        ("imit-ral", 0),
        ("imit-ral", 1),
    ]  # in the ablation's order
    with pytest.raises(ValueError, match="loss has no variant imit-gail"):
        ablation_jobs("loss", ["Hopper-v5"], [0], tmp_path, tmp_path, ["imit-gail", "rank-pal"])


def test_per_seed_table_lists_each_finished_run_in_seed_order(tmp_path: Path) -> None:
    jobs = ablation_jobs("rankings", ["Hopper-v5"], [0, 1], tmp_path / "runs", tmp_path / "archive")
    curves = {
        ("auto", 0): "1000,10\n2000,90\n3000,20\n4000,85\n",  # from 2k on (half of 4k): 90, 20, 85
        ("auto", 1): "1000,5\n2000,30\n3000,40\n4000,50\n",  # never at 80
        ("vanilla", 0): "1000,95\n2000,99\n",  # stopped before --steps: not listed
    }
    for variant, job in jobs:
        if (variant.label, job.seed) in curves:
            job.archived.mkdir(parents=True)
            (job.archived / "metrics.csv").write_text("env_steps,normalized_score\n" + curves[variant.label, job.seed])
    rows = summarize(jobs, [4000], steps=4000)
    assert rows[0]["runs"] == [
        {
            "seed": 0,
            "first_step_at_threshold": 2000,
            "late_median": 85.0,
            "late_min": 20.0,
            "late_max": 90.0,
            "curve_mean": 51.2,  # (10 + 90 + 20 + 85) / 4 = 51.25, rounded half to even
        },
        {
            "seed": 1,
            "first_step_at_threshold": None,
            "late_median": 40.0,
            "late_min": 30.0,
            "late_max": 50.0,
            "curve_mean": 31.2,  # (5 + 30 + 40 + 50) / 4 = 31.25
        },
    ]
    assert rows[1]["runs"] == []
    table = per_seed_table(rows, steps=4000).splitlines()
    assert table[0] == "| env | variant | first step at >= 80, per seed | median / min / max over 2k-4k, per seed |"
    assert table[2] == "| Hopper-v5 | auto | 2k, never | 85.0 / 20.0 / 90.0, 40.0 / 30.0 / 50.0 |"
    assert table[3] == "| Hopper-v5 | vanilla | - | - |"


def test_common_options_and_a_namespaced_env(tmp_path: Path) -> None:
    jobs = ablation_jobs(
        "preference-noise",
        ["rankgame/Door-v0"],
        [3],
        tmp_path / "runs",
        tmp_path / "archive",
        ["noise-0.2"],
        "--preset modern",
    )
    [(_, job)] = jobs
    assert job.out == tmp_path / "runs" / "preference-noise" / "noise-0.2" / "rankgame__Door-v0__s3"
    assert job.train_args == "--preset modern --rankings.pref-noise 0.2"  # the variant's own options come last


def test_success_metric_is_the_success_rate_in_percent(tmp_path: Path) -> None:
    jobs = ablation_jobs("preference-noise", ["rankgame/Door-v0"], [0], tmp_path, tmp_path, ["noise-0"])
    [(_, job)] = jobs
    job.archived.mkdir(parents=True)
    (job.archived / "metrics.csv").write_text("env_steps,normalized_score,eval_success\n1000,12.5,0.4\n2000,50,1\n")
    [row] = summarize(jobs, [1000, 2000], steps=2000, metric="success")
    assert [point["mean"] for point in row["at"]] == [40.0, 100.0]
    assert row["curve_mean"] == 70.0
    [row] = summarize(jobs, [1000], steps=2000)
    assert row["at"][0]["mean"] == 12.5
