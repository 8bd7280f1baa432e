"""Weights & Biases logging (``--wandb``): an offline run read back from its W&B file, resume into the
same W&B run, and the one-line error without the package."""

from __future__ import annotations

import csv
import struct
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_main

from rankgame.cli import main
from rankgame.tracking import RUN_ID_NAME, flat_settings


def test_flat_settings_joins_sections_with_dots_and_writes_lists_as_text() -> None:
    config = {"method": "dac", "seed": 0, "expert": None, "sac": {"lr": 1e-3, "hidden_sizes": [256, 256]}}
    assert flat_settings(config) == {"method": "dac", "seed": 0, "sac.lr": 1e-3, "sac.hidden_sizes": "256 256"}


def _wandb_records(run_file: Path) -> Iterator[object]:
    """The records of an offline W&B run file: a 7-byte header, then a LevelDB-style log of 32 KiB
    blocks, each record a 7-byte header (checksum, length, type: full, first, middle or last) and data
    that is one ``wandb_internal_pb2.Record``."""
    from wandb.proto import wandb_internal_pb2

    raw, pos, chunks, block = run_file.read_bytes(), 7, [], 32768
    while pos + 7 <= len(raw):
        if block - pos % block < 7:  # a block's tail too short for a header is padding
            pos += block - pos % block
            continue
        _, length, kind = struct.unpack("<IHB", raw[pos : pos + 7])
        data, pos = raw[pos + 7 : pos + 7 + length], pos + 7 + length
        if kind == 0:
            break
        chunks = [data] if kind in (1, 2) else [*chunks, data]
        if kind in (1, 4):
            record = wandb_internal_pb2.Record()
            record.ParseFromString(b"".join(chunks))
            yield record


def _stop_wandb() -> None:
    """Stop this process's W&B service, as the end of a ``rankgame train`` process does: the service
    writes a run's file in the background, and the file is whole only once it has stopped."""
    import wandb

    wandb.teardown()


def _history(out: Path) -> dict[int, dict[str, str]]:
    """Every W&B run file's logged rows under ``OUT/wandb``, by step (later files win)."""
    rows: dict[int, dict[str, str]] = {}
    for run_file in sorted(out.glob("wandb/offline-run-*/run-*.wandb")):
        for record in _wandb_records(run_file):
            if record.WhichOneof("record_type") == "history":
                items = {item.key or "/".join(item.nested_key): item.value_json for item in record.history.item}
                rows[int(items["_step"])] = items
    return rows


def test_an_offline_wandb_run_holds_the_settings_every_row_and_the_policy(
    toy_expert_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("WANDB_MODE", raising=False)  # offline is the default
    out = tmp_path / "run"
    args = ["train", *TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--eval-every", "400", "--out", str(out)]
    assert main([*args, "--steps", "800", "--wandb"]) == 0
    _stop_wandb()
    run_id = (out / RUN_ID_NAME).read_text().strip()
    (run_file,) = out.glob(f"wandb/offline-run-*-{run_id}/run-{run_id}.wandb")
    records = list(_wandb_records(run_file))
    (run,) = [r.run for r in records if r.WhichOneof("record_type") == "run"]
    settings = {item.key: item.value_json for item in run.config.update}
    assert settings["method"] == '"rank-pal-auto"' and settings["sac.hidden_sizes"] == '"64 64"'
    (artifact,) = [r.artifact for r in records if r.WhichOneof("record_type") == "artifact"]
    assert artifact.type == "model" and [entry.path for entry in artifact.manifest.contents] == ["policy.msgpack"]
    with (out / "metrics.csv").open() as handle:
        logged = {int(row["env_steps"]): row for row in csv.DictReader(handle)}
    history = _history(out)
    assert sorted(history) == sorted(logged) == [400, 800]
    for step, row in logged.items():
        assert float(history[step]["normalized_score"]) == pytest.approx(float(row["normalized_score"]), rel=1e-5)
    # A resumed run logs into the same W&B run, from where its checkpoint left off.
    assert main([*args, "--steps", "1200", "--wandb", "--resume"]) == 0
    _stop_wandb()
    assert (out / RUN_ID_NAME).read_text().strip() == run_id
    assert len(list(out.glob(f"wandb/offline-run-*-{run_id}"))) >= 1
    assert sorted(_history(out)) == [400, 800, 1200]


def test_wandb_without_the_package_is_a_one_line_error(
    capsys: pytest.CaptureFixture[str], toy_expert_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "wandb", None)  # import wandb now raises ImportError
    out = tmp_path / "run"
    result = run_main(
        capsys,
        "train",
        *TOY_TRAIN_ARGS,
        "--expert",
        str(toy_expert_file),
        "--steps",
        "400",
        "--out",
        str(out),
        "--wandb",
    )
    assert_one_line_error(result, "--wandb needs Weights & Biases: pip install 'rankgame[wandb]'")
    assert not out.exists()
