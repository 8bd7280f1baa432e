"""Normalized score of ranking-game methods at fixed step budgets, over seeds and tasks.

Launches ``rankgame train`` for every (env, method, seed) not already finished under ``--root``,
one per core of ``--cores``, each pinned to its core (the fastest way to use a 2-core machine), then prints
the mean and standard deviation across seeds of the normalized score at each checkpoint step
(``--at``), as JSON and as a Markdown table, beside the authors' released RANK-PAL(auto) curves.

Each finished run's ``metrics.csv`` and ``config.json`` are copied to ``--archive`` (by default
``benchmarks/results/sample-efficiency``, kept in the repository), so the table can be rebuilt, and
runs are not repeated, without the run folders (which hold large checkpoints).

    python benchmarks/sample_efficiency.py --envs Hopper-v5 HalfCheetah-v5 Walker2d-v5 \
        --methods rank-pal-auto rank-ral-auto --seeds 0 1 2 --steps 300000 --root runs/sample-eff
    python benchmarks/sample_efficiency.py --summarize-only --root runs/sample-eff ...
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: Authors' released RANK-PAL(auto) curves, normalized by their experts (LfO, 1 expert trajectory).
PUBLISHED = {
    "Hopper-v5": {100_000: 86, 300_000: 92},
    "HalfCheetah-v5": {100_000: 47, 300_000: 79},
    "Walker2d-v5": {100_000: 18, 300_000: 65},
    "Ant-v5": {100_000: 22, 300_000: 80},
    "Humanoid-v5": {100_000: 5, 300_000: 68},
}


def run_dir(root: Path, env: str, method: str, seed: int) -> Path:
    return root / f"{env}__{method}__s{seed}"


def archive_if_finished(out: Path, archived: Path) -> None:
    """Copy the ``metrics.csv`` and ``config.json`` of a run that wrote its final policy to ``archived``."""
    if (out / "policy.msgpack").exists() and not (archived / "metrics.csv").exists():
        archived.mkdir(parents=True, exist_ok=True)
        for name in ("metrics.csv", "config.json"):
            shutil.copyfile(out / name, archived / name)


def launch_all(args: argparse.Namespace) -> None:
    """Run the missing trainings, one single-core process pinned to each of ``--cores``."""
    jobs = []
    for env in args.envs:
        for method in args.methods:
            for seed in args.seeds:
                out, archived = run_dir(args.root, env, method, seed), run_dir(args.archive, env, method, seed)
                archive_if_finished(out, archived)
                if not (archived / "metrics.csv").exists():
                    jobs.append((out, archived, env, method, seed))
    running: dict[str, tuple[subprocess.Popen, Path, Path]] = {}  # core -> (process, run folder, archive)
    for out, archived, env, method, seed in jobs:
        cmd = [sys.executable, "-m", "rankgame.cli", "train", "--env", env, "--method", method, "--seed", str(seed)]
        cmd += ["--steps", str(args.steps), "--out", str(out), "--no-progress"]
        cmd += ["--resume"] if (out / "checkpoint.npz").exists() else []
        core = _free_core(running, args.cores)
        out.parent.mkdir(parents=True, exist_ok=True)
        log = open(f"{out}.log", "a")  # noqa: SIM115  (closed when the process ends)
        proc = subprocess.Popen(["taskset", "-c", core, *cmd], stdout=log, stderr=log, env=os.environ)
        running[core] = (proc, out, archived)
    for core in list(running):
        _wait_and_archive(*running.pop(core))


def _free_core(running: dict[str, tuple[subprocess.Popen, Path, Path]], cores: list[str]) -> str:
    """A core with no run on it, waiting for one to finish (and archiving it) if all are busy."""
    while True:
        for core in cores:
            if core not in running:
                return core
            if running[core][0].poll() is not None:
                _wait_and_archive(*running.pop(core))
                return core
        time.sleep(5)


def _wait_and_archive(proc: subprocess.Popen, out: Path, archived: Path) -> None:
    proc.wait()
    archive_if_finished(out, archived)


def score_at(out: Path, archived: Path, step: int) -> float | None:
    """Normalized score logged at ``step`` by the run (or its archived copy), or None if not got there."""
    path = out / "metrics.csv"
    if not path.exists():
        path = archived / "metrics.csv"
    if not path.exists():
        return None
    with path.open() as handle:
        for row in csv.DictReader(handle):
            if int(row["env_steps"]) == step:
                return float(row["normalized_score"])
    return None


def summarize(args: argparse.Namespace) -> dict:
    table = {}
    for env in args.envs:
        for method in args.methods:
            for step in args.at:
                runs = [(run_dir(args.root, env, method, s), run_dir(args.archive, env, method, s)) for s in args.seeds]
                scores = [score_at(out, archived, step) for out, archived in runs]
                scores = [s for s in scores if s is not None]
                table[f"{env} {method} {step}"] = {
                    "env": env,
                    "method": method,
                    "step": step,
                    "seeds": len(scores),
                    "mean": round(float(np.mean(scores)), 1) if scores else None,
                    "std": round(float(np.std(scores)), 1) if scores else None,
                    "published_rank_pal_auto": PUBLISHED.get(env, {}).get(step),
                }
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", nargs="+", default=["Hopper-v5", "HalfCheetah-v5", "Walker2d-v5"])
    parser.add_argument("--methods", nargs="+", default=["rank-pal-auto", "rank-ral-auto"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--at", nargs="+", type=int, default=[100_000, 300_000])
    parser.add_argument("--root", type=Path, default=Path("runs/sample-efficiency"))
    parser.add_argument("--archive", type=Path, default=Path("benchmarks/results/sample-efficiency"))
    parser.add_argument("--cores", nargs="+", default=["0", "1"], help="CPU cores to pin one run each to")
    parser.add_argument("--summarize-only", action="store_true")
    args = parser.parse_args()
    if not args.summarize_only:
        launch_all(args)
    table = summarize(args)
    print(json.dumps(list(table.values())))
    print("\n| env | method | steps | seeds | normalized score | published RANK-PAL(auto) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for row in table.values():
        score = "-" if row["mean"] is None else f"{row['mean']} ± {row['std']}"
        print(
            f"| {row['env']} | {row['method']} | {row['step']} | {row['seeds']} | {score} | "
            f"{row['published_rank_pal_auto'] or '-'} |"
        )


if __name__ == "__main__":
    main()
