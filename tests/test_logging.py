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


def _tensorboard_scalars(tb_dir: Path, tag: str) -> list[tuple[int, float]]:
    """The (step, value) points TensorBoard shows for ``tag``: the event files are read in the order they
    were written, and a session start at step P hides the earlier events at steps >= P (its purge rule)."""
    from tensorboardX.proto.event_pb2 import Event, SessionLog

    points: list[tuple[int, float]] = []
    for path in sorted(tb_dir.glob("events.out.tfevents.*"), key=lambda p: p.stat().st_mtime_ns):
        data = path.read_bytes()
        offset = 0
        while offset < len(data):  # TFRecord framing: length (8 bytes), its CRC (4), payload, CRC (4)
            length = int.from_bytes(data[offset : offset + 8], "little")
            event = Event.FromString(data[offset + 12 : offset + 12 + length])
            offset += 12 + length + 4
            if event.HasField("session_log") and event.session_log.status == SessionLog.START:
                points = [(step, value) for step, value in points if step < event.step]
            for value in event.summary.value:
                if value.tag == tag:
                    points.append((event.step, value.simple_value))
    return points


def test_resume_keeps_every_tensorboard_point_once(tmp_path: Path) -> None:
    first = RunLogger(tmp_path, ["env_steps", "eval_return"])
    for step in (1000, 2000, 3000):  # killed after logging 3000; its checkpoint was at 2000
        first.log({"env_steps": step, "eval_return": step / 1000})
    first.close()
    for path in (tmp_path / "tb").iterdir():  # event files are named by the second they start in
        path.rename(path.with_name(path.name + ".first"))
    resumed = RunLogger(tmp_path, ["env_steps", "eval_return"], resume_step=2000)
    resumed.log({"env_steps": 3000, "eval_return": 3.5})
    resumed.close()
    assert _tensorboard_scalars(tmp_path / "tb", "eval_return") == [(1000, 1.0), (2000, 2.0), (3000, 3.5)]


def test_tensorboard_gets_the_settings_as_hyperparameters(tmp_path: Path) -> None:
    from tensorboardX.proto.event_pb2 import Event
    from tensorboardX.proto.plugin_hparams_pb2 import HParamsPluginData

    config = {"method": "dacfo", "seed": 3, "tensorboard": True, "sac": {"lr": 0.001, "hidden_sizes": [64, 64]}}
    logger = RunLogger(tmp_path, ["env_steps", "eval_return"], hparams=config)
    logger.close()
    starts = []
    for path in (tmp_path / "tb").glob("events.out.tfevents.*"):
        data, offset = path.read_bytes(), 0
        while offset < len(data):
            length = int.from_bytes(data[offset : offset + 8], "little")
            event = Event.FromString(data[offset + 12 : offset + 12 + length])
            offset += 12 + length + 4
            for value in event.summary.value:
                if value.tag == "_hparams_/session_start_info":
                    starts.append(HParamsPluginData.FromString(value.metadata.plugin_data.content).session_start_info)
    assert len(starts) == 1
    hparams = starts[0].hparams
    assert hparams["method"].string_value == "dacfo" and hparams["seed"].number_value == 3
    assert hparams["tensorboard"].bool_value is True
    assert hparams["sac.lr"].number_value == 0.001 and hparams["sac.hidden_sizes"].string_value == "64 64"
