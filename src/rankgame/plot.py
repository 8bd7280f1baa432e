"""Learning curves from one or more run folders (``rankgame plot``); needs the ``plot`` extra.

With ``seeds=True`` runs whose folder names differ only in a seed suffix (``..._s0``, ``...-seed1``,
``...__s2``) are drawn as one curve: the mean over seeds with a band of one standard deviation, at
the steps every seed logged.
"""

from __future__ import annotations

import csv
import re
import textwrap
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rankgame.atomic import atomic_write
from rankgame.errors import RankGameError

#: Characters per line of a figure title; longer titles wrap onto more lines (the figure is 7 inches wide).
TITLE_WIDTH = 70
#: A run folder name's seed suffix: ``_s0``, ``-s12``, ``__seed3``.
SEED_SUFFIX = re.compile(r"[_-]+s(?:eed)?\d+$")


def pyplot() -> Any:
    """``matplotlib.pyplot`` drawing to files (the Agg backend); a one-line :class:`RankGameError` if the
    ``plot`` extra is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise RankGameError("plotting needs matplotlib: pip install 'rankgame[plot]'") from None
    return plt


def read_curve(run: Path, column: str, max_steps: int | None = None) -> tuple[list[int], list[float]]:
    """``(env_steps, values)`` of one column of ``run/metrics.csv`` (rows without a value, and rows past
    ``max_steps`` environment steps if given, skipped)."""
    path = run / "metrics.csv"
    if not path.is_file():
        raise RankGameError(f"no metrics.csv in {run}")
    steps, values = [], []
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        for needed in ("env_steps", column):
            if needed not in (reader.fieldnames or []):
                raise RankGameError(f"{path} has no column {needed!r} (columns: {', '.join(reader.fieldnames or [])})")
        for line, row in enumerate(reader, start=2):
            if not row.get(column):
                continue
            try:
                step, value = int(row["env_steps"]), float(row[column])
            except (TypeError, ValueError):
                raise RankGameError(f"{path}, line {line}: env_steps and {column} must be numbers") from None
            if max_steps is None or step <= max_steps:
                steps.append(step)
                values.append(value)
    if not steps:
        past = "" if max_steps is None else f" at or below {max_steps} steps"
        raise RankGameError(f"{path} has no value of {column!r}{past}")
    return steps, values


def group_by_seed(runs: Sequence[Path]) -> dict[str, list[Path]]:
    """Run folders grouped by their parent folder and their name without its seed suffix, in the order
    first seen, and keyed by that name (prefixed by the parent where two parents hold the same name)."""
    groups: dict[tuple[Path, str], list[Path]] = {}
    for run in map(Path, runs):
        groups.setdefault((run.parent, SEED_SUFFIX.sub("", run.name)), []).append(run)
    names = Counter(name for _, name in groups)
    return {(f"{parent}/{name}" if names[name] > 1 else name): group for (parent, name), group in groups.items()}


def mean_curve(curves: Sequence[tuple[list[int], list[float]]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps ``(T,)`` logged by every curve, and the mean ``(T,)`` and standard deviation ``(T,)`` there."""
    by_step = [dict(zip(steps, values, strict=True)) for steps, values in curves]
    common = sorted(set.intersection(*(set(curve) for curve in by_step)))
    table = np.array([[curve[step] for step in common] for curve in by_step], np.float64).reshape(len(curves), -1)
    return np.asarray(common), table.mean(axis=0), table.std(axis=0)


def plot_runs(
    runs: Sequence[Path],
    out: Path,
    column: str = "normalized_score",
    seeds: bool = False,
    labels: Sequence[str] | None = None,
    title: str | None = None,
    max_steps: int | None = None,
) -> Path:
    """Draw ``column`` against environment steps for every run (or every group of seeds) into ``out``.

    ``labels``, if given, names the curves in order: one per run, or one per group of seeds.
    ``max_steps``, if given, ends every curve there (to compare runs of different lengths).
    """
    groups = list(group_by_seed(runs).items()) if seeds else [(Path(run).name, [Path(run)]) for run in runs]
    if labels is not None and len(labels) != len(groups):
        unit = "group of seeds" if seeds else "run"
        count = f"{len(groups)} curve{'s' if len(groups) != 1 else ''}"
        raise RankGameError(f"got {len(labels)} labels for {count} (one label per {unit})")
    if labels is not None:
        groups = [(label, group) for label, (_, group) in zip(labels, groups, strict=True)]
    return plot_groups(groups, out, column, seeds, title, max_steps)


def plot_groups(
    groups: Sequence[tuple[str, Sequence[Path]]],
    out: Path,
    column: str = "normalized_score",
    seeds: bool = True,
    title: str | None = None,
    max_steps: int | None = None,
) -> Path:
    """Draw one curve per ``(label, run folders)`` group into ``out``: with ``seeds`` the mean over the
    group's runs with a band of one standard deviation, else the group's single run."""
    if max_steps is not None and max_steps <= 0:
        raise RankGameError(f"--max-steps must be positive (got {max_steps})")
    # Read every curve before drawing, so that a bad run fails before a figure is made.
    curves = []
    for label, group in groups:
        if seeds:
            steps, mean, std = mean_curve([read_curve(Path(run), column, max_steps) for run in group])
            if len(steps) == 0:
                raise RankGameError(f"the runs of {label} share no logged step")
            curves.append((f"{label} ({len(group)} seed{'s' if len(group) > 1 else ''})", steps, mean, std))
        else:
            steps, values = read_curve(Path(group[0]), column, max_steps)
            curves.append((label, steps, values, None))
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, steps, values, std in curves:
        (line,) = ax.plot(steps, values, label=label)
        if std is not None:
            ax.fill_between(steps, values - std, values + std, color=line.get_color(), alpha=0.2)
    if title:
        ax.set_title(textwrap.fill(title, TITLE_WIDTH))
    ax.set_xlabel("environment steps")
    ax.set_ylabel(column)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    image_format = out.suffix.lstrip(".").lower()
    if image_format not in fig.canvas.get_supported_filetypes():
        plt.close(fig)
        raise RankGameError(f"cannot write a {out.suffix or 'suffix-less'} image; name --out *.png, *.pdf or *.svg")
    atomic_write(out, lambda handle: fig.savefig(handle, format=image_format, dpi=120))
    plt.close(fig)
    return out
