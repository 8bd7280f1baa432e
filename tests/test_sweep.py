"""``rankgame sweep``: the grid and its folders, bad input, and a real local Ray sweep that survives the
death of its workers and a resume of the driver."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import assert_one_line_error, run_main

from rankgame.errors import RankGameError
from rankgame.sweep import SWEEP_FILE, SweepSpec, check_grid, load_spec, parse_variant, trials, write_grid

TOY = "rankgame/PointGoal-v0"

#: Options of a small, fast ranking game on the toy task (see conftest.TOY_TRAIN_ARGS), as sweep options.
TOY_OPTIONS = {
    "sac.hidden-sizes": "64 64",
    "sac.batch-size": "64",
    "sac.start-steps": "400",
    "sac.update-after": "400",
    "sac.update-every": "40",
    "reward.batch-size": "256",
    "eval-every": "400",
    "eval-episodes": "2",
    "checkpoint-every": "400",
    "tensorboard": "false",
}


def _rows(run: Path) -> list[dict[str, str]]:
    with (run / "metrics.csv").open() as handle:
        return list(csv.DictReader(handle))


def test_the_grid_names_one_run_folder_per_trial(tmp_path: Path) -> None:
    label, options = parse_variant("reward.lr=1e-4,leader.patience=1")
    assert (label, options) == ("reward.lr=1e-4,leader.patience=1", {"reward.lr": "1e-4", "leader.patience": "1"})
    spec = SweepSpec(("Hopper-v5", "rankgame/Door-v0"), ("rank-pal-auto",), (0, 1), 1000, {label: options})
    grid = trials(spec, tmp_path)
    assert [t.name for t in grid] == [
        "Hopper-v5__rank-pal-auto__s0__reward.lr=1e-4,leader.patience=1",
        "Hopper-v5__rank-pal-auto__s1__reward.lr=1e-4,leader.patience=1",
        "rankgame__Door-v0__rank-pal-auto__s0__reward.lr=1e-4,leader.patience=1",
        "rankgame__Door-v0__rank-pal-auto__s1__reward.lr=1e-4,leader.patience=1",
    ]
    argv = grid[0].argv
    assert argv[argv.index("--out") + 1] == str(tmp_path / grid[0].name)
    assert argv[-4:] == ("--reward.lr", "1e-4", "--leader.patience", "1")
    plain = trials(SweepSpec(("Hopper-v5",), ("dacfo",), (3,), 10, options={"tensorboard": "false"}), tmp_path)
    assert plain[0].name == "Hopper-v5__dacfo__s3" and "--no-tensorboard" in plain[0].argv


def test_a_spec_file_holds_the_grid_and_bad_ones_are_named(tmp_path: Path) -> None:
    path = tmp_path / "grid.toml"
    path.write_text(
        'envs = ["Hopper-v5"]\nmethods = ["rank-pal-auto", "dacfo"]\nseeds = [0, 1]\nsteps = 20000\n'
        '[options]\neval-episodes = 10\n[variants.lr-low]\n"reward.lr" = 1e-4\n'
    )
    spec = load_spec(path)
    assert spec == SweepSpec(
        ("Hopper-v5",),
        ("rank-pal-auto", "dacfo"),
        (0, 1),
        20000,
        {"lr-low": {"reward.lr": "0.0001"}},
        {"eval-episodes": "10"},
    )
    path.write_text('envs = ["Hopper-v5"]\nmethods = ["dacfo"]\nseeds = [0]\nsteps = 10\nseed = 1\n')
    with pytest.raises(RankGameError, match="unknown key 'seed'"):
        load_spec(path)
    path.write_text('envs = ["Hopper-v5"]\nmethods = ["dacfo"]\nsteps = 10\n')
    with pytest.raises(RankGameError, match="missing key 'seeds'"):
        load_spec(path)


def test_a_resume_with_another_grid_is_refused(tmp_path: Path) -> None:
    spec = SweepSpec(("Hopper-v5",), ("dacfo",), (0,), 100)
    with pytest.raises(RankGameError, match="nothing to resume"):
        check_grid(tmp_path, spec, resume=True)
    check_grid(tmp_path, spec, resume=False)
    write_grid(tmp_path, spec)
    assert json.loads((tmp_path / SWEEP_FILE).read_text())["grid"]["methods"] == ["dacfo"]
    with pytest.raises(RankGameError, match="already holds a sweep"):
        check_grid(tmp_path, spec, resume=False)
    with pytest.raises(RankGameError, match="has another grid"):
        check_grid(tmp_path, SweepSpec(("Hopper-v5",), ("dacfo",), (0, 1), 100), resume=True)
    check_grid(tmp_path, spec, resume=True)  # the same grid: fine


@pytest.mark.parametrize(
    ("options", "fragment"),
    [
        (["--methods", "airl"], "invalid choice: 'airl'"),
        (["--methods", "dacfo", "--envs", "NoSuchTask-v0"], "NoSuchTask-v0"),
        (["--methods", "dacfo", "--option", "reward.nonsense=1"], "unrecognized arguments: --reward.nonsense 1"),
        (["--methods", "dacfo", "--seeds"], "expected at least one argument"),
        (["--methods", "dacfo", "--variant", "reward.lr"], "name=value pairs"),
        (["--methods", "dacfo", "--address", "127.0.0.1:1"], "cannot reach a Ray cluster at 127.0.0.1:1"),
        (["--methods", "dacfo", "--address", "nowhere"], "give HOST:PORT"),
    ],
)
def test_bad_grids_are_one_line_errors_and_start_nothing(
    options: list[str], fragment: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    argv = ["sweep", "--envs", TOY, "--seeds", "0", "--steps", "100", "--out", str(tmp_path / "sweep"), *options]
    result = run_main(capsys, *argv)
    assert_one_line_error(result, fragment)
    assert not (tmp_path / "sweep").exists()


def _session(pid: int) -> int:
    """The session id of process ``pid`` (-1 when it is gone)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return -1
    return int(stat.rsplit(")", 1)[1].split()[3])  # after "pid (comm)": state, ppid, pgrp, session


def _session_processes(session: int, prefix: bytes = b"") -> list[int]:
    """PIDs of the processes of ``session`` whose command line starts with ``prefix``: those of the sweep
    this test started in its own session (its driver, and the Ray instance and workers the driver
    started), never those of another sweep running on the same machine."""
    pids = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit() or _session(int(proc.name)) != session:
            continue
        try:
            cmdline = (proc / "cmdline").read_bytes()
        except OSError:
            continue
        if cmdline.startswith(prefix):
            pids.append(int(proc.name))
    return pids


def _kill_all(pids: list[int]) -> None:
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="finds Ray's worker processes through /proc")
def test_a_local_ray_sweep_survives_killed_workers_and_a_killed_driver(toy_expert_file: Path, tmp_path: Path) -> None:
    pytest.importorskip("ray")
    out = tmp_path / "sweep"
    argv = [sys.executable, "-m", "rankgame", "sweep", "--envs", TOY, "--methods", "rank-pal-auto", "dacfo"]
    argv += ["--seeds", "0", "1", "--steps", "1600", "--cores", "2", "--out", str(out)]
    argv += ["--option", f"expert={toy_expert_file}"]
    for name, value in TOY_OPTIONS.items():
        argv += ["--option", f"{name}={value}"]
    driver = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 300
    while time.time() < deadline and not list(out.glob("*/checkpoint.npz")):
        time.sleep(0.5)
    killed = _session_processes(driver.pid, b"ray::ImplicitFunc")
    assert killed, "no trial was running"
    _kill_all(killed)  # the workers die: Ray restarts their trials, which resume from their checkpoints
    while time.time() < deadline and len([p for p in out.glob("*/metrics.csv") if len(_rows(p.parent)) >= 1]) < 3:
        time.sleep(0.5)
    _kill_all(_session_processes(driver.pid))  # then the driver dies too, with its Ray instance
    driver.wait()
    resumed = subprocess.run([*argv, "--resume"], capture_output=True, text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stdout[-3000:] + resumed.stderr[-3000:]
    summary = json.loads(resumed.stdout[resumed.stdout.rindex("{\n") :])
    assert summary["trials"] == 4 and summary["failed"] == []
    for run in sorted(p for p in out.iterdir() if p.is_dir() and not p.name.startswith(".")):
        steps = [int(row["env_steps"]) for row in _rows(run)]
        assert steps == list(range(400, 1601, 400)), (run.name, steps)  # every evaluation once, none missing
