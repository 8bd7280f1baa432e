"""``rankgame.stats`` against numbers worked out by hand, and ``rankgame report`` on a handmade archive."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error, run_main

from rankgame.report import SAC_TRUE_REWARD, find_run_folders, read_run, seed_kind, write_report
from rankgame.stats import (
    iqm,
    mean_and_sample_std,
    performance_profile,
    probability_of_improvement,
    stratified_bootstrap_ci,
)

ARCHIVE = Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "sample-efficiency"

# ------------------------------------------------------------------------------------------------ stats


def test_iqm_uses_fractional_weights_at_the_quartiles() -> None:
    # n = 4: the middle two values.
    assert iqm([100.0, 1.0, 3.0, 2.0]) == pytest.approx((2 + 3) / 2)
    # n = 8: the middle four, as scipy.stats.trim_mean(x, 0.25) gives.
    assert iqm([8, 1, 7, 2, 6, 3, 5, 4]) == pytest.approx((3 + 4 + 5 + 6) / 4)
    # n = 3: masses [0, 1/3], [1/3, 2/3], [2/3, 1] cover 1/12, 1/3, 1/12 of [1/4, 3/4]: weights 1/6, 2/3, 1/6.
    assert iqm([12.0, 0.0, 3.0]) == pytest.approx(0 / 6 + 3 * 2 / 3 + 12 / 6)
    # n = 5: masses of 1/5 cover 0, 0.15, 0.2, 0.15, 0 of the middle half: weights 0, 0.3, 0.4, 0.3, 0.
    assert iqm([1, 2, 3, 4, 100]) == pytest.approx(0.3 * 2 + 0.4 * 3 + 0.3 * 4)
    # n = 6: weights 0, 1/6, 1/3, 1/3, 1/6, 0.
    assert iqm([50, 0, 40, 10, 30, 20]) == pytest.approx(10 / 6 + 20 / 3 + 30 / 3 + 40 / 6)
    assert iqm([7.0]) == 7.0 and iqm([1.0, 4.0]) == pytest.approx(2.5)
    # A (runs, tasks) matrix is pooled; with an axis, one IQM per row.
    assert iqm([[1.0, 100.0], [3.0, 2.0]]) == pytest.approx(2.5)
    np.testing.assert_allclose(iqm(np.array([[1, 2, 3, 100], [12, 0, 3, 3]]), axis=-1), [2.5, 3.0])
    with pytest.raises(ValueError):
        iqm([])


def test_stratified_bootstrap_resamples_within_each_task() -> None:
    # Task A's runs all score 0, task B's 10: every stratified sample holds two of each, so the pooled mean
    # is always 5 (resampling across tasks would move it).
    interval = stratified_bootstrap_ci([[0.0, 0.0], [10.0, 10.0]], lambda tasks: np.concatenate(tasks).mean())
    assert tuple(interval) == (5.0, 5.0, 5.0)


def test_stratified_bootstrap_takes_percentiles_of_the_statistic() -> None:
    # Two runs scoring 0 and 1: a sample's mean is 0, 0.5 or 1 with chances 1/4, 1/2, 1/4. The 2.5% and 97.5%
    # quantiles are then 0 and 1, the 30% and 70% ones both 0.5.
    mean = lambda tasks: float(tasks[0].mean())  # noqa: E731
    assert tuple(stratified_bootstrap_ci([[0.0, 1.0]], mean, n_boot=4000, seed=1)) == (0.5, 0.0, 1.0)
    assert tuple(stratified_bootstrap_ci([[0.0, 1.0]], mean, n_boot=4000, seed=1, level=0.4)) == (0.5, 0.5, 0.5)
    # The vectorized form sees the same samples, one per row.
    scores = [[1.0, 5.0, 2.0], [7.0, 3.0]]
    loop = stratified_bootstrap_ci(scores, lambda tasks: iqm(np.concatenate(tasks)), n_boot=300, seed=3)
    batched = stratified_bootstrap_ci(
        scores, lambda tasks: iqm(np.concatenate(tasks, axis=-1), axis=-1), n_boot=300, seed=3, vectorized=True
    )
    np.testing.assert_allclose(tuple(batched), tuple(loop))
    assert loop.estimate == pytest.approx(iqm([1, 5, 2, 7, 3])) and loop.low <= loop.estimate <= loop.high


def test_probability_of_improvement_counts_every_pair_of_runs() -> None:
    # Task 1: X [1, 2] against Y [2, 0]: 1 < 2, 1 > 0, 2 = 2 (half), 2 > 0: (2 + 0.5) / 4. Task 2: 5 > 1.
    interval = probability_of_improvement([[1.0, 2.0], [5.0]], [[2.0, 0.0], [1.0]], n_boot=500)
    assert interval.estimate == pytest.approx(((2 + 0.5) / 4 + 1.0) / 2)
    assert 0.0 <= interval.low <= interval.estimate <= interval.high <= 1.0
    # Every run of X above every run of Y: 1 in every sample.
    assert tuple(probability_of_improvement([[3.0, 4.0]], [[1.0, 2.0]], n_boot=200)) == (1.0, 1.0, 1.0)
    with pytest.raises(ValueError):
        probability_of_improvement([[1.0]], [[1.0], [2.0]])


def test_performance_profile_is_the_fraction_strictly_above() -> None:
    profile = performance_profile([10.0, 50.0, 90.0, 100.0], [0.0, 50.0, 95.0, 100.0])
    np.testing.assert_allclose(profile, [4 / 4, 2 / 4, 1 / 4, 0 / 4])
    np.testing.assert_allclose(performance_profile([[10.0, 50.0], [90.0, 100.0]], [20.0]), [3 / 4])


def test_mean_and_sample_std_divides_by_n_minus_one() -> None:
    mean, std = mean_and_sample_std([1.0, 2.0, 3.0, 6.0])
    assert mean == pytest.approx(3.0)
    assert std == pytest.approx(math.sqrt(((1 - 3) ** 2 + (2 - 3) ** 2 + 0 + (6 - 3) ** 2) / 3))
    assert mean_and_sample_std([5.0]) == (5.0, None)
    with pytest.raises(ValueError):
        mean_and_sample_std([])


def test_seed_kind_labels_tuning_held_out_and_mixed() -> None:
    assert seed_kind([0, 1, 99]) == "tuning"
    assert seed_kind([100, 101]) == "held-out"
    assert seed_kind([2, 100]) == "mixed"


# ----------------------------------------------------------------------------------------------- report

#: Handmade scores at 100k, 200k and 300k steps, by (task, method, seed).
SCORES = {
    ("Hopper-v5", "rank-pal-auto", 0): (20.0, 85.0, 90.0),
    ("Hopper-v5", "rank-pal-auto", 1): (40.0, 60.0, 100.0),
    ("Hopper-v5", "rank-pal-auto", 2): (30.0, 90.0, 40.0),
    ("Hopper-v5", "rank-ral-auto", 100): (10.0, 50.0, 70.0),
    ("Hopper-v5", "rank-ral-auto", 101): (85.0, 40.0, 95.0),
    ("Hopper-v5", "rank-ral-auto", 102): (5.0, 20.0, 30.0),
    ("Walker2d-v5", "rank-pal-auto", 0): (10.0, 20.0, 30.0),
    ("Walker2d-v5", "rank-pal-auto", 1): (50.0, 60.0, 70.0),
    ("Walker2d-v5", "rank-pal-auto", 2): (0.0, 10.0, 20.0),
    ("Walker2d-v5", "rank-ral-auto", 100): (60.0, 70.0, 80.0),
    ("Walker2d-v5", "rank-ral-auto", 101): (20.0, 30.0, 40.0),
    ("Walker2d-v5", "rank-ral-auto", 102): (40.0, 50.0, 60.0),
}


def make_run(folder: Path, env: str, method: str, seed: int, scores: tuple[float, ...]) -> Path:
    folder.mkdir(parents=True)
    command = f"rankgame train --env {env} --method {method} --seed {seed} --steps 300000"
    config = {"command": command, "env": env, "method": method, "seed": seed, "steps": 300_000, "old_key": 1}
    (folder / "config.json").write_text(json.dumps(config))
    rows = [f"{100_000 * (i + 1)},{10 * i},{score * 30},{score}" for i, score in enumerate(scores)]
    (folder / "metrics.csv").write_text("env_steps,wall_s,eval_return,normalized_score\n" + "\n".join(rows) + "\n")
    return folder


@pytest.fixture
def archive(tmp_path: Path) -> Path:
    root = tmp_path / "archive"
    for (env, method, seed), scores in SCORES.items():
        make_run(root / f"{env}__{method}__s{seed}", env, method, seed, scores)
    return root


def section(page: str, title: str) -> str:
    """The text of the page's section headed ``title`` (up to the next heading of any level)."""
    start = page.index(f"{title}\n")
    end = page.find("\n#", start + len(title))
    return page[start : end if end >= 0 else None]


def table_row(text: str, *first: str) -> list[str]:
    """The cells of the table row of ``text`` whose first cells are ``first``."""
    for line in text.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.startswith("|") and cells[: len(first)] == list(first):
            return cells
    raise AssertionError(f"no row {first} in:\n{text}")


def test_report_tables_match_the_scores_worked_out_by_hand(archive: Path, tmp_path: Path) -> None:
    out = tmp_path / "page"
    page_path = write_report([archive], out, n_boot=300)
    assert page_path == out / "results.md"
    page = page_path.read_text()
    assert len(page.splitlines()) < 300
    assert {p.name for p in (out / "img").iterdir()} == {
        "performance_profile.png",
        "curves_Hopper-v5.png",
        "curves_Walker2d-v5.png",
    }
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in (out / "img").iterdir())
    assert "![performance profiles](img/performance_profile.png)" in page

    # Headline tables: rows are (method, variant), columns the tasks in Table 1 order.
    at_100k = section(page, "## Normalized score at 100k steps")
    assert "| method | variant | Hopper-v5 | Walker2d-v5 |" in at_100k
    hopper_pal = [20.0, 40.0, 30.0]
    mean = sum(hopper_pal) / 3
    std = math.sqrt(sum((x - mean) ** 2 for x in hopper_pal) / 2)  # 30 ± 10
    walker_ral = [60.0, 20.0, 40.0]  # 40 ± 20
    walker_mean = sum(walker_ral) / 3
    walker_std = math.sqrt(sum((x - walker_mean) ** 2 for x in walker_ral) / 2)
    assert table_row(at_100k, "rank-pal-auto", "archive")[2] == f"{mean:.1f} ± {std:.1f} (3, tuning)"
    assert table_row(at_100k, "rank-ral-auto", "archive")[3] == f"{walker_mean:.1f} ± {walker_std:.1f} (3, held-out)"
    # The published figures beside ours, labelled.
    curve_label = "*authors' released LfO curve at 100k (moving average of 20 evaluations)*"
    curve = table_row(at_100k, "rank-pal-auto", curve_label)
    assert curve[2:] == ["86", "18"]
    paper = table_row(at_100k, "rank-ral-auto", "*paper, Table 1 (LfO) at 2M (mean ± std, 5 seeds)*")
    assert paper[2:] == ["99.34 ± 0.2", "93.24 ± 1.25"]

    at_300k = section(page, "## Normalized score at 300k steps")
    hopper_pal_300k = [90.0, 100.0, 40.0]
    mean = sum(hopper_pal_300k) / 3
    std = math.sqrt(sum((x - mean) ** 2 for x in hopper_pal_300k) / 2)
    assert table_row(at_300k, "rank-pal-auto", "archive")[2] == f"{mean:.1f} ± {std:.1f} (3, tuning)"
    longest = section(page, "## Normalized score at the longest horizon each cell's runs share")
    assert table_row(longest, "rank-pal-auto", "archive")[2] == f"{mean:.1f} ± {std:.1f} (3, tuning) at 300k"
    assert "gradient step" not in longest  # no bc run: every step is an environment step

    # IQM at 100k of rank-pal-auto pools its six runs: sorted 0, 10, 20, 30, 40, 50 weighted 0, 1/6, 1/3, 1/3,
    # 1/6, 0.
    aggregates = section(page, "### Interquartile mean (IQM) of the normalized score")
    pal_iqm = 10 / 6 + 20 / 3 + 30 / 3 + 40 / 6
    assert table_row(aggregates, "rank-pal-auto", "archive")[2].startswith(f"{pal_iqm:.1f} [")
    assert "(6 runs, 2 tasks, tuning)" in table_row(aggregates, "rank-pal-auto", "archive")[2]

    # Probability of improvement at 100k: Hopper 6 of 9 pairs, Walker2d 2 of 9; mean 4/9.
    improvement = section(page, "### Probability of improvement at 100k steps")
    cells = table_row(improvement, "rank-pal-auto · archive")
    assert cells[2].startswith(f"{(6 / 9 + 2 / 9) / 2:.2f} [") and cells[2].endswith("(2 tasks)")
    assert table_row(improvement, "rank-ral-auto · archive")[1].startswith(f"{1 - 4 / 9:.2f} [")

    # Stability: Hopper's PAL runs first reach 80 at 200k (s0: later 90), 300k (s1: none later) and 200k
    # (s2: later 40 < 50): 1 of 2. Its RAL runs: only s101 reaches 80 (at 100k; later 40, 95): 1 of 2.
    stability = section(page, "## Stability")
    row = table_row(stability, "Hopper-v5", "rank-pal-auto", "archive")
    assert row[3:] == [
        "3 (tuning)",
        "0",
        "1/2 = 50.0%",
        f"{(90 + 100 + 40) / 3:.1f}",
        "-",  # these runs log no selection criterion
        "1/3 · -",  # s2 ends at 40
        f"{(90 + 100 + 90) / 3:.1f}",
        "300k",
    ]
    row = table_row(stability, "Hopper-v5", "rank-ral-auto", "archive")
    assert row[3:6] == ["3 (held-out)", "2 (s100, s102)", "1/2 = 50.0%"]
    assert table_row(stability, "Walker2d-v5", "rank-pal-auto", "archive")[4:6] == ["3 (s0, s1, s2)", "-"]

    # Runs: every folder, its seed, steps reached and command.
    runs = section(page, "## Runs")
    row = table_row(runs, f"`{archive / 'Hopper-v5__rank-ral-auto__s101'}`")
    assert row[1:] == [
        "archive",
        "Hopper-v5",
        "rank-ral-auto",
        "101 (held-out)",
        "300k of 300k",
        "`rankgame train --env Hopper-v5 --method rank-ral-auto --seed 101 --steps 300000`",
    ]
    assert sum(line.startswith("| `") for line in runs.splitlines()) == len(SCORES)


def test_variants_are_the_folders_that_hold_the_runs(tmp_path: Path) -> None:
    scores = (10.0, 20.0, 30.0)
    a = make_run(tmp_path / "default" / "Hopper-v5__rank-pal-auto__s0", "Hopper-v5", "rank-pal-auto", 0, scores)
    make_run(tmp_path / "k-1" / "Hopper-v5__rank-pal-auto__s0", "Hopper-v5", "rank-pal-auto", 0, scores)
    make_run(tmp_path / "nested" / "backward" / "run_s0", "Hopper-v5", "rank-pal-auto", 0, scores)
    make_run(
        tmp_path / "sweep" / "Hopper-v5__rank-pal-auto__s0__reward.lr=1e-4", "Hopper-v5", "rank-pal-auto", 0, scores
    )
    found = find_run_folders([a, tmp_path / "k-1", tmp_path / "nested", a, tmp_path / "sweep"])
    assert [variant for _, variant in found] == ["default", "k-1", "nested/backward", "sweep"]
    page = write_report([a, tmp_path / "k-1", tmp_path / "nested", tmp_path / "sweep"], tmp_path / "out", n_boot=50)
    table = section(page.read_text(), "## Normalized score at 100k steps")
    for variant in ("default", "k-1", "nested/backward", "sweep/reward.lr=1e-4"):
        assert table_row(table, "rank-pal-auto", variant)[2] == "10.0 (1, tuning)"


def test_the_stability_table_shows_the_score_of_the_policy_each_run_selected(tmp_path: Path) -> None:
    criteria = {0: ("0.2", "0.9", "0.5"), 1: ("0.3", "nan", "0.7"), 2: None}  # s2 selects nothing
    for seed, ratios in criteria.items():
        folder = make_run(
            tmp_path / "sel" / f"Hopper-v5__rank-pal-auto__s{seed}",
            "Hopper-v5",
            "rank-pal-auto",
            seed,
            SCORES[("Hopper-v5", "rank-pal-auto", seed)],
        )
        if ratios is not None:
            lines = (folder / "metrics.csv").read_text().splitlines()
            rows = [f"{line},{ratio}" for line, ratio in zip(lines[1:], ratios, strict=True)]
            (folder / "metrics.csv").write_text("\n".join([lines[0] + ",selection/learned_return", *rows]) + "\n")
    page = write_report([tmp_path / "sel"], tmp_path / "out", n_boot=50).read_text()
    row = table_row(section(page, "## Stability"), "Hopper-v5", "rank-pal-auto", "sel")
    # s0 selects its 200k evaluation (85), s1 its 300k one (100)
    assert row[7:9] == [f"{(85 + 100) / 2:.1f} (2 runs)", "1/3 · 0/2"]  # s2 ends at 40


def test_a_rankgame_expert_run_is_the_sac_reference_normalized_with_the_shipped_expert(tmp_path: Path) -> None:
    from rankgame.data.experts import load_shipped_expert

    expert = load_shipped_expert("Hopper-v5")
    top, bottom = float(expert.returns.mean()), float(expert.metadata["random_return_mean"])
    folder = tmp_path / "sac-ref" / "Hopper-v5-s100"
    folder.mkdir(parents=True)
    config = {"command": "rankgame expert ...", "env": "Hopper-v5", "seed": 100, "steps": 20}
    (folder / "config.json").write_text(json.dumps({**config, "trajectories": 1, "sac": {}}))
    half = bottom + 0.5 * (top - bottom)
    (folder / "metrics.csv").write_text(f"env_steps,eval_return\n10,{bottom}\n20,{half}\n")
    run = read_run(folder, "sac-ref")
    assert (run.method, run.seed, run.steps.tolist()) == (SAC_TRUE_REWARD, 100, [10, 20])
    np.testing.assert_allclose(run.scores, [0.0, 50.0], atol=1e-6)
    page = write_report([tmp_path / "sac-ref"], tmp_path / "out", n_boot=50).read_text()
    assert table_row(section(page, "## Stability"), "Hopper-v5", SAC_TRUE_REWARD)[2] == "sac-ref"


def test_bad_inputs_are_one_line_errors(capsys: pytest.CaptureFixture[str], archive: Path, tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "out"
    result = run_main(capsys, "report", str(archive), str(empty), "--out", str(out))
    assert_one_line_error(result, f"{empty} holds no metrics.csv and no run folders with one")
    assert not out.exists()  # nothing written
    taken = tmp_path / "a-file"
    taken.write_text("not a folder")
    assert_one_line_error(run_main(capsys, "report", str(archive), "--out", str(taken)), "is a file")
    assert taken.read_text() == "not a folder"
    no_config = tmp_path / "no-config"
    no_config.mkdir()
    (no_config / "metrics.csv").write_text("env_steps,normalized_score\n100000,1\n")
    assert_one_line_error(run_main(capsys, "report", str(no_config), "--out", str(out)), "no config.json")
    assert_one_line_error(run_main(capsys, "report", str(archive), "--out", str(out), "--boot", "0"), "--boot")
    assert not out.exists()


def test_report_without_matplotlib_says_which_extra(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], archive: Path, tmp_path: Path
) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # makes the import fail
    out = tmp_path / "out"
    result = run_main(capsys, "report", str(archive), "--out", str(out))
    assert_one_line_error(result, "plotting needs matplotlib: pip install 'rankgame[plot]'")
    assert not out.exists()


def test_report_on_the_sample_efficiency_archive(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "page"
    result = run_main(capsys, "report", str(ARCHIVE), "--out", str(out), "--boot", "200")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == str(out / "results.md")
    page = (out / "results.md").read_text()
    assert "Hopper-v5" in page and (out / "img" / "curves_Hopper-v5.png").is_file()


def test_a_claim_is_judged_from_its_comparisons_with_runs_on_both_sides() -> None:
    from rankgame.claims import Claim, Comparison, Side, judge

    ours, theirs, absent = Side("rank-pal-auto", "a", "ours"), Side("dacfo", label="theirs"), Side("bco")
    values = {("ours", "Hopper-v5"): [60.0, 80.0], ("theirs", "Hopper-v5"): [50.0, 40.0, 30.0]}

    def values_at(side: Side, env: str, step: int, metric: str) -> list[float]:
        return values.get((side.name, env), []) if step == 100_000 else []

    def collapses(side: Side, env: str) -> tuple[int, int] | None:
        return {"ours": (1, 10), "theirs": (0, 0)}.get(side.name)

    higher = Claim("x", "s", "p", (Comparison(ours, theirs, "Hopper-v5"), Comparison(ours, absent, "Hopper-v5")))
    measured, verdict = judge(higher, values_at, collapses)
    # means 70 and 40: the comparison holds; the other has no runs on one side and does not count.
    # sample stds: sqrt((10^2 + 10^2) / 1) = 14.1 and sqrt((10^2 + 0 + 10^2) / 2) = 10.0
    assert verdict == "reproduced"
    assert measured == (
        "ours vs theirs, Hopper-v5 at 100k: 70.0 ± 14.1 (n=2) vs 40.0 ± 10.0 (n=3); "
        "ours vs bco, Hopper-v5 at 100k: not run"
    )
    reversed_claim = Claim("x", "s", "p", (Comparison(theirs, ours, "Hopper-v5"),))
    assert judge(reversed_claim, values_at, collapses)[1] == "not reproduced"
    assert judge(Claim("x", "s", "p", (Comparison(ours, absent, "Ant-v5"),)), values_at, collapses)[1] == "not run"
    steadier = Claim("x", "s", "p", (Comparison(ours, theirs, "Hopper-v5"),), kind="steadier")
    assert judge(steadier, values_at, collapses) == ("ours vs theirs, Hopper-v5: theirs never reached 80", "not run")


def test_the_claims_table_reads_success_rates_and_names_the_verdict(tmp_path: Path) -> None:
    from rankgame.claims import CLAIMS
    from rankgame.report import claims_section, group_runs, load_runs

    door = [claim for claim in CLAIMS if claim.statement.startswith("offline preferences solve Pen and Door")][0]
    for label, method, successes in (
        ("pal-pref", "rank-pal-pref", (1.0, 0.5)),
        ("pal-auto", "rank-pal-auto", (0.2, 0.0)),
    ):
        for seed, success in enumerate(successes):
            run = tmp_path / "ablations-door" / "preferences" / label / f"rankgame__Door-v0__s{seed}"
            run.mkdir(parents=True)
            (run / "metrics.csv").write_text(f"env_steps,normalized_score,eval_success\n60000,10,{success}\n")
            config = {"command": "c", "env": "rankgame/Door-v0", "method": method, "seed": seed, "steps": 60000}
            (run / "config.json").write_text(json.dumps(config))
    lines = claims_section(group_runs(load_runs([tmp_path / "ablations-door"])), 80.0, 50.0)
    (row,) = [line for line in lines if line.startswith(f"| {door.statement}")]
    # success rates: (1.0 + 0.5) / 2 = 75% against (0.2 + 0.0) / 2 = 10%; sample stds
    # sqrt(2 * 0.25^2) = 35% and sqrt(2 * 0.1^2) = 14%
    assert "rankgame/Door-v0 at 60k: 75% ± 35% (n=2) vs 10% ± 14% (n=2)" in row
    assert row.endswith("| **reproduced** |")


def test_the_longest_horizon_says_that_bcs_steps_are_gradient_steps(archive: Path, tmp_path: Path) -> None:
    make_run(archive / "Hopper-v5__bc__s0", "Hopper-v5", "bc", 0, (5.0,))
    page = write_report([archive], tmp_path / "page", n_boot=50).read_text()
    longest = section(page, "## Normalized score at the longest horizon each cell's runs share")
    assert "For `bc`, which never acts in the environment, a step is a gradient step." in longest
    assert table_row(longest, "bc", "archive")[2] == "5.0 (1, tuning) at 100k"
