"""Window summaries of a metrics column (benchmarks/eval_windows.py), by hand."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from eval_windows import read_column, window_summary  # noqa: E402


def test_a_window_counts_its_evaluations_those_above_the_threshold_and_their_mean(tmp_path: Path) -> None:
    (tmp_path / "metrics.csv").write_text("env_steps,eval_success\n10000,0\n20000,0.2\n30000,0.4\n40000,\n")
    values = read_column(tmp_path, "eval_success")
    assert values == {10000: 0.0, 20000: 0.2, 30000: 0.4}  # an empty cell is no evaluation of that column
    summary = window_summary(values, 10000, 30000, above=0.0)
    assert summary["evaluations"] == 3 and summary["above"] == 2 and summary["max"] == 0.4
    assert summary["mean"] == pytest.approx(0.2)
    assert window_summary(values, 50000, 60000, above=0.0) == {"evaluations": 0, "above": 0, "mean": None, "max": None}
    with pytest.raises(ValueError, match="no column 'normalized_score'"):
        read_column(tmp_path, "normalized_score")
