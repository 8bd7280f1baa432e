"""Per-run summaries of a ``metrics.csv`` column over windows of environment steps.

For each run folder and each ``--windows FROM:TO`` (inclusive, in environment steps) it prints the
number of evaluations in the window, how many of them are above ``--above``, and their mean and
maximum, as JSON lines and as a Markdown table. With ``--column eval_success --above 0`` this counts
the Pen and Door evaluations in which any episode succeeded; with ``--column normalized_score`` it
gives, for instance, the mean of the evaluations from 250k to 300k.

    python benchmarks/eval_windows.py benchmarks/results/pen/expert-sac/rank-pal-pref-s0 \\
        --column eval_success --above 0 --windows 10000:500000 510000:1000000
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path


def read_column(run: Path, column: str) -> dict[int, float]:
    """The run's ``column`` by evaluation step; a ``ValueError`` with a one-line reason if it is missing."""
    path = run / "metrics.csv"
    if not path.is_file():
        raise ValueError(f"{path} not found")
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    if not rows or column not in rows[0]:
        raise ValueError(f"{path} has no column {column!r}")
    return {int(row["env_steps"]): float(row[column]) for row in rows if row[column] != ""}


def window_summary(values: dict[int, float], start: int, stop: int, above: float) -> dict[str, float | int | None]:
    """Count, count above ``above``, mean and maximum of the values logged at steps in ``[start, stop]``."""
    inside = [value for step, value in values.items() if start <= step <= stop]
    return {
        "evaluations": len(inside),
        "above": sum(value > above for value in inside),
        "mean": sum(inside) / len(inside) if inside else None,
        "max": max(inside) if inside else None,
    }


def parse_window(text: str) -> tuple[int, int]:
    """``FROM:TO`` as two step counts, ``FROM <= TO``."""
    try:
        start, stop = (int(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a window like 10000:500000") from None
    if start > stop:
        raise argparse.ArgumentTypeError(f"window {text!r} ends before it starts")
    return start, stop


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+", help="run folders holding metrics.csv")
    parser.add_argument("--column", default="normalized_score")
    parser.add_argument("--above", type=float, default=0.0, help="threshold of the 'above' count")
    parser.add_argument("--windows", type=parse_window, nargs="+", required=True, help="FROM:TO step windows")
    args = parser.parse_args(argv)
    try:
        columns = {run: read_column(run, args.column) for run in args.runs}
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    rows = []
    for run, values in columns.items():
        for start, stop in args.windows:
            rows.append({"run": str(run), "from": start, "to": stop, **window_summary(values, start, stop, args.above)})
            print(json.dumps(rows[-1]))
    print(f"\n| run | window | evaluations | above {args.above:g} | mean {args.column} | max |")
    print("| --- | --- | --- | --- | --- | --- |")
    for row in rows:
        mean = "-" if row["mean"] is None else f"{row['mean']:.3g}"
        top = "-" if row["max"] is None else f"{row['max']:.3g}"
        window = f"{row['from'] // 1000}k-{row['to'] // 1000}k"
        print(f"| {row['run']} | {window} | {row['evaluations']} | {row['above']} | {mean} | {top} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
