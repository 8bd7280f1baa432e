"""Run logs: whole rows under one header, also when a run logged by an older version is resumed."""

from __future__ import annotations

import csv
from pathlib import Path

from rankgame.logging import RunLogger


def _read(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_resume_trims_rows_after_the_checkpoint(tmp_path: Path) -> None:
    (tmp_path / "metrics.csv").write_text("env_steps,eval_return\n1000,1\n2000,2\n3000,3\n")
    logger = RunLogger(tmp_path, ["env_steps", "eval_return"], tensorboard=False, resume_step=2000)
    logger.log({"env_steps": 3000, "eval_return": 3.5})
    logger.close()
    rows = _read(tmp_path / "metrics.csv")
    assert [(row["env_steps"], row["eval_return"]) for row in rows] == [("1000", "1"), ("2000", "2"), ("3000", "3.5")]


def test_resuming_an_older_log_appends_its_missing_columns(tmp_path: Path) -> None:
    (tmp_path / "metrics.csv").write_text("env_steps,eval_return\n1000,1\n2000,2\n")
    columns = ["env_steps", "eval_return", "eval_success", "wall_s"]
    logger = RunLogger(tmp_path, columns, tensorboard=False, resume_step=2000)
    assert logger.columns == columns
    logger.log({"env_steps": 3000, "eval_return": 3.0, "eval_success": 0.5, "wall_s": 9.0})
    logger.close()
    lines = (tmp_path / "metrics.csv").read_text().splitlines()
    assert lines == [
        "env_steps,eval_return,eval_success,wall_s",
        "1000,1,,",
        "2000,2,,",
        "3000,3,0.5,9",
    ]


def test_an_existing_log_keeps_its_own_column_order(tmp_path: Path) -> None:
    (tmp_path / "metrics.csv").write_text("eval_return,env_steps\n1,1000\n")
    logger = RunLogger(tmp_path, ["env_steps", "eval_return"], tensorboard=False, resume_step=1000)
    logger.log({"env_steps": 2000, "eval_return": 2.0})
    logger.close()
    assert (tmp_path / "metrics.csv").read_text().splitlines() == ["eval_return,env_steps", "1,1000", "2,2000"]
