"""Learning curves from one or more run folders (``rankgame plot``); needs the ``plot`` extra."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from rankgame.errors import RankGameError


def read_curve(run: Path, column: str) -> tuple[list[int], list[float]]:
    """``(env_steps, values)`` of one column of ``run/metrics.csv`` (rows without a value skipped)."""
    path = run / "metrics.csv"
    if not path.is_file():
        raise RankGameError(f"no metrics.csv in {run}")
    steps, values = [], []
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        if column not in (reader.fieldnames or []):
            raise RankGameError(f"{path} has no column {column!r} (columns: {', '.join(reader.fieldnames or [])})")
        for row in reader:
            if row.get(column):
                steps.append(int(row["env_steps"]))
                values.append(float(row[column]))
    return steps, values


def plot_runs(runs: Sequence[Path], out: Path, column: str = "normalized_score") -> Path:
    """Draw ``column`` against environment steps for every run into the image ``out``."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise RankGameError("plotting needs matplotlib: pip install 'rankgame[plot]'") from None
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for run in runs:
        steps, values = read_curve(Path(run), column)
        ax.plot(steps, values, label=Path(run).name)
    ax.set_xlabel("environment steps")
    ax.set_ylabel(column)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
