"""Runs that never fail silently: a diverging player, a signal, a full disk, a resumed run's settings,
and the leftovers of killed writes."""

from __future__ import annotations

import csv
import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_cli

from rankgame.checkpoint import load_checkpoint
from rankgame.cli import main

SHORT = ("--eval-every", "200", "--eval-episodes", "1", "--checkpoint-every", "200")


def _args(expert: Path, out: Path, *extra: str) -> list[str]:
    return ["train", *TOY_TRAIN_ARGS, "--expert", str(expert), "--out", str(out), *SHORT, *extra]


def _steps(out: Path) -> list[int]:
    with (out / "metrics.csv").open(newline="") as handle:
        return [int(row["env_steps"]) for row in csv.DictReader(handle)]


def _all_finite(path: Path) -> bool:
    _, arrays = load_checkpoint(path)
    return all(np.isfinite(a).all() for a in arrays.values() if np.issubdtype(a.dtype, np.floating))


def test_a_diverging_critic_stops_the_run_and_keeps_a_finite_resumable_checkpoint(
    toy_expert_file: Path, tmp_path: Path
) -> None:
    out = tmp_path / "critic"
    result = run_cli(*_args(toy_expert_file, out, "--steps", "2000", "--sac.critic-lr", "1e10"))
    # The first SAC update (step 400, after 400 random steps) diverges; the checkpoint of step 200 is kept.
    assert_one_line_error(result, "step 400: the SAC critic loss is not finite")
    assert result.returncode == 1 and "checkpoint.npz, step 200) is intact and resumable" in result.stderr
    assert load_checkpoint(out / "checkpoint.npz")[0]["env_steps"] == 200 and _all_finite(out / "checkpoint.npz")
    # Resuming loads that checkpoint; with the same settings it diverges again at the same step.
    again = run_cli("train", "--out", str(out), "--resume")
    assert_one_line_error(again, "step 400: the SAC critic loss is not finite")


def test_a_diverging_reward_stops_the_run_before_anything_is_written(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "reward"
    result = run_cli(*_args(toy_expert_file, out, "--steps", "400", "--reward.lr", "1e30"))
    assert_one_line_error(result, "step 40: the reward loss is not finite; no checkpoint was written yet")
    assert not (out / "checkpoint.npz").exists() and not (out / "policy.msgpack").exists()


def test_sigterm_checkpoints_the_step_reached_and_resume_continues_from_it(
    toy_expert_file: Path, tmp_path: Path
) -> None:
    out = tmp_path / "term"
    command = [sys.executable, "-m", "rankgame", *_args(toy_expert_file, out, "--steps", "4000")]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 240
    while time.time() < deadline and not ((out / "metrics.csv").exists() and len(_steps(out)) >= 3):
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    step = int(load_checkpoint(out / "checkpoint.npz")[0]["env_steps"])
    assert 600 <= step < 4000
    assert f"stopped by SIGTERM at step {step}" in err and f"--resume continues from step {step}" in err
    assert _all_finite(out / "checkpoint.npz")
    # A killed write leaves a temporary file behind; the resumed run removes it.
    (out / ".checkpoint.npz.12345.tmp").write_bytes(b"partial")
    resumed = run_cli("train", "--out", str(out), "--resume", "--steps", "1200")
    assert resumed.returncode == 0, resumed.stderr
    assert not list(out.glob(".*.tmp"))
    steps = _steps(out)
    assert steps == sorted(set(steps)) and steps[-1] == 1200 and (step // 200) * 200 in steps
    assert b"\r" not in (out / "metrics.csv").read_bytes()  # one line ending throughout


def test_a_resumed_run_takes_its_settings_from_its_folder(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "settings"
    first = run_cli(*_args(toy_expert_file, out, "--steps", "400", "--method", "rank-ral-auto", "--seed", "3"))
    assert first.returncode == 0, first.stderr
    # Neither --method nor --seed repeated (nor the other options): the run's own settings are used.
    longer = run_cli("train", "--out", str(out), "--resume", "--steps", "600", "--eval-every", "100")
    assert longer.returncode == 0, longer.stderr
    summary = json.loads(longer.stdout)
    assert summary["method"] == "rank-ral-auto" and summary["env_steps"] == 600
    assert _steps(out) == [200, 400, 500, 600]
    saved = json.loads((out / "config.json").read_text())
    assert saved["seed"] == 3 and saved["sac"]["hidden_sizes"] == [64, 64] and saved["eval_every"] == 100
    assert_one_line_error(
        run_cli("train", "--out", str(out), "--resume", "--seed", "4"), "--seed 4 differs from the run's 3"
    )
    assert_one_line_error(
        run_cli("train", "--out", str(out), "--resume", "--k", "5"), "--rankings.k 5.0 differs from the run's 10.0"
    )
    # A finished run resumed prints its final evaluation as valid JSON.
    finished = run_cli("train", "--out", str(out), "--resume")
    assert finished.returncode == 0, finished.stderr
    assert json.loads(finished.stdout)["eval_return"] == pytest.approx(summary["eval_return"])


def test_a_full_disk_names_the_file_and_says_the_last_checkpoint_is_intact(
    toy_expert_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import rankgame.run

    out = tmp_path / "full"
    real_save = rankgame.run.save_checkpoint
    saves: list[int] = []

    def save_once_then_fail(path: Path, metadata: dict, arrays: dict) -> None:
        if saves:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        saves.append(metadata["env_steps"])
        real_save(path, metadata, arrays)

    monkeypatch.setattr(rankgame.run, "save_checkpoint", save_once_then_fail)
    assert main(_args(toy_expert_file, out, "--steps", "800")) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"cannot write {out / 'checkpoint.npz'}: No space left on device" in err
    assert f"the last good checkpoint ({out / 'checkpoint.npz'}, step 200) is intact and resumable" in err
    assert load_checkpoint(out / "checkpoint.npz")[0]["env_steps"] == 200
