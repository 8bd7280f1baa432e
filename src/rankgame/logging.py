"""Run logs: a CSV file with fixed columns and, optionally, TensorBoard event files."""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path


class RunLogger:
    """Append rows of scalar metrics to ``DIR/metrics.csv`` and TensorBoard (``DIR/tb``).

    Columns are fixed when the logger is made; a row may leave some empty. Rows are flushed as they
    are written, so a killed run leaves only whole rows behind.
    """

    def __init__(
        self,
        out_dir: Path,
        columns: Sequence[str],
        tensorboard: bool = True,
        step_key: str = "env_steps",
        purge_step: int | None = None,
    ):
        self.path = Path(out_dir) / "metrics.csv"
        self.columns = list(columns)
        self.step_key = step_key
        new_file = not self.path.exists() or self.path.stat().st_size == 0
        self._file = self.path.open("a", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns, extrasaction="ignore")
        if new_file:
            self._writer.writeheader()
            self._file.flush()
        self._tb = None
        if tensorboard:
            from tensorboardX import SummaryWriter

            # purge_step makes TensorBoard drop events a resumed run logs again.
            self._tb = SummaryWriter(str(Path(out_dir) / "tb"), purge_step=purge_step)

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


def _fmt(value: float | int) -> str | int:
    return value if isinstance(value, int) else f"{value:.6g}"
