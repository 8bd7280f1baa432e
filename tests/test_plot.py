"""Learning-curve helpers: seed grouping and the mean over seeds, by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import assert_one_line_error, run_cli

from rankgame.cli import main
from rankgame.plot import group_by_seed, mean_curve, read_curve


def test_runs_are_grouped_by_name_without_the_seed_suffix() -> None:
    runs = [Path(p) for p in ("a/Hopper__pal__s0", "a/Hopper__pal__s1", "b/Hopper__ral-seed0", "c/plain")]
    groups = group_by_seed(runs)
    assert list(groups) == ["Hopper__pal", "Hopper__ral", "plain"]
    assert groups["Hopper__pal"] == runs[:2] and groups["plain"] == [runs[3]]


def test_runs_of_the_same_name_in_different_folders_stay_apart() -> None:
    runs = [Path(p) for p in ("default/Hopper__pal__s0", "lr/Hopper__pal__s0", "default/Hopper__pal__s1")]
    groups = group_by_seed(runs)
    assert groups == {"default/Hopper__pal": [runs[0], runs[2]], "lr/Hopper__pal": [runs[1]]}


def test_mean_curve_uses_the_steps_every_seed_logged() -> None:
    steps, mean, std = mean_curve([([10, 20, 30], [1.0, 2.0, 6.0]), ([10, 20], [3.0, 4.0])])
    np.testing.assert_array_equal(steps, [10, 20])
    np.testing.assert_allclose(mean, [2.0, 3.0])
    np.testing.assert_allclose(std, [1.0, 1.0])


def test_plot_seeds_draws_one_band_per_group(tmp_path: Path) -> None:
    for seed, values in enumerate(([10, 50], [30, 70])):
        run = tmp_path / f"run_s{seed}"
        run.mkdir()
        (run / "metrics.csv").write_text(f"env_steps,normalized_score\n1000,{values[0]}\n2000,{values[1]}\n")
    out = tmp_path / "mean.png"
    assert main(["plot", str(tmp_path / "run_s0"), str(tmp_path / "run_s1"), "--seeds", "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_plot_labels_name_the_curves_and_must_match_their_number(tmp_path: Path) -> None:
    import matplotlib

    runs = []
    for name in ("a_s0", "a_s1", "b_s0"):
        run = tmp_path / name
        run.mkdir()
        (run / "metrics.csv").write_text("env_steps,normalized_score\n1000,1\n2000,2\n")
        runs.append(str(run))
    out = tmp_path / "labelled.svg"
    with matplotlib.rc_context({"svg.fonttype": "none"}):  # keep legend text as text, so it can be read back
        assert main(["plot", *runs, "--seeds", "--labels", "first", "second", "--title", "T", "--out", str(out)]) == 0
    svg = out.read_text()
    assert "first (2 seeds)" in svg and "second (1 seed)" in svg and ">T<" in svg
    assert_one_line_error(run_cli("plot", *runs, "--labels", "x", "y"), "got 2 labels for 3 curves (one label per run)")


def test_max_steps_ends_every_curve_there(tmp_path: Path) -> None:
    long, short = tmp_path / "long_s0", tmp_path / "short_s0"
    for run, rows in ((long, "1000,1\n2000,2\n3000,3\n"), (short, "1000,5\n2000,6\n")):
        run.mkdir()
        (run / "metrics.csv").write_text("env_steps,normalized_score\n" + rows)
    assert read_curve(long, "normalized_score", max_steps=2500) == ([1000, 2000], [1.0, 2.0])
    assert read_curve(long, "normalized_score") == ([1000, 2000, 3000], [1.0, 2.0, 3.0])
    out = tmp_path / "cut.png"
    assert main(["plot", str(long), str(short), "--seeds", "--max-steps", "2000", "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert_one_line_error(
        run_cli("plot", str(long), "--max-steps", "500"), "no value of 'normalized_score' at or below 500"
    )
    assert_one_line_error(run_cli("plot", str(long), "--max-steps", "0"), "--max-steps must be positive (got 0)")


def test_a_metrics_file_without_steps_or_with_text_is_a_one_line_error(tmp_path: Path) -> None:
    no_steps, text = tmp_path / "no_steps", tmp_path / "text"
    for run, content in (
        (no_steps, "step,normalized_score\n1000,1\n"),
        (text, "env_steps,normalized_score\n1000,high\n"),
    ):
        run.mkdir()
        (run / "metrics.csv").write_text(content)
    assert_one_line_error(run_cli("plot", str(no_steps)), "has no column 'env_steps'")
    assert_one_line_error(run_cli("plot", str(text)), "line 2: env_steps and normalized_score must be numbers")
