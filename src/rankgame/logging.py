"""Run logs: a CSV file with fixed columns and, optionally, TensorBoard event files with the run's settings
as hyperparameters (:func:`rankgame.tracking.write_hparams`)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from rankgame.atomic import atomic_write_bytes


class RunLogger:
    """Append rows of scalar metrics to ``DIR/metrics.csv`` and TensorBoard (``DIR/tb``).

    Columns are fixed when the logger is made (an existing file keeps its own order, with new columns
    appended: :func:`extend_header`); a row may leave some empty. Rows are flushed as they
    are written, so a killed run leaves only whole rows behind. ``resume_step`` continues a run from
    its checkpoint at that step: CSV rows after it are dropped (they will be logged again) and
    TensorBoard hides the earlier events after it (a purge from ``resume_step + 1``: the checkpoint's
    own step was logged before it was saved), so no row is duplicated or missing. ``hparams``, the run's
    settings as JSON, are recorded in TensorBoard's HParams tab.
    """

    def __init__(
        self,
        out_dir: Path,
        columns: Sequence[str],
        tensorboard: bool = True,
        step_key: str = "env_steps",
        resume_step: int | None = None,
        hparams: Mapping[str, Any] | None = None,
    ) -> None:
        self.path = Path(out_dir) / "metrics.csv"
        self.step_key = step_key
        if resume_step is not None:
            trim_metrics(self.path, resume_step)
        new_file = not self.path.exists() or self.path.stat().st_size == 0
        self.columns = list(columns) if new_file else extend_header(self.path, columns)
        self._file = self.path.open("a", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns, extrasaction="ignore", lineterminator="\n")
        if new_file:
            self._writer.writeheader()
            self._file.flush()
        self._tb = None
        if tensorboard:
            from tensorboardX import SummaryWriter

            purge_step = None if resume_step is None else resume_step + 1
            self._tb = SummaryWriter(str(Path(out_dir) / "tb"), purge_step=purge_step)
            if hparams is not None:
                from rankgame.tracking import write_hparams

                write_hparams(self._tb, hparams)

    def log(self, row: Mapping[str, float | int]) -> None:
        """Write one row; keys outside the columns go to TensorBoard only."""
        self._writer.writerow({k: _fmt(v) for k, v in row.items() if k in self.columns})
        self._file.flush()
        if self._tb is not None:
            step = int(row[self.step_key])
            for key, value in row.items():
                if key != self.step_key and isinstance(value, (int, float)) and math.isfinite(value):
                    self._tb.add_scalar(key, value, step)

    def close(self) -> None:
        self._file.close()
        if self._tb is not None:
            self._tb.close()


def trim_metrics(path: Path, last_step: int) -> None:
    """Atomically keep only the header and the rows of ``path`` whose first column is <= ``last_step``."""
    if not path.exists():
        return
    rows = _read_rows(path)
    if not rows:
        return
    _write_rows(path, [rows[0]] + [row for row in rows[1:] if row and row[0].isdigit() and int(row[0]) <= last_step])


def extend_header(path: Path, columns: Sequence[str]) -> list[str]:
    """The columns of an existing CSV file, with those of ``columns`` it lacks appended (the file is then
    rewritten atomically, its rows padded with empty cells), so that a run logged by an older version
    resumes with whole rows under a matching header."""
    rows = _read_rows(path)
    header = rows[0]
    missing = [column for column in columns if column not in header]
    if missing:
        _write_rows(path, [header + missing] + [row + [""] * len(missing) for row in rows[1:]])
    return header + missing


def _read_rows(path: Path) -> list[list[str]]:
    with path.open(newline="") as handle:
        return list(csv.reader(handle))


def _write_rows(path: Path, rows: list[list[str]]) -> None:
    """Replace ``path`` atomically with ``rows`` as CSV."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    atomic_write_bytes(path, buffer.getvalue().encode())


def _fmt(value: float | int) -> str | int:
    return value if isinstance(value, int) else f"{value:.6g}"
