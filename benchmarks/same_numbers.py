"""Fixed-seed runs whose logged numbers must not change when the code is reorganized.

Each case is a short ``rankgame`` command (a few thousand steps, evaluations on) that together
touch every ranking source, both losses, both leaders, LfD, preferences with noise, the
non-stationary switch, a tuned recipe, the ablation options and the expert trainer. ``--record DIR``
writes each case's ``metrics.csv`` under ``DIR/CASE``; ``--compare DIR`` runs them again and reports,
per case, whether every logged value except the wall-clock columns is identical.

Runs are single-threaded XLA pinned to one core, the setup in which fixed-seed results repeat:

    python benchmarks/same_numbers.py --record benchmarks/results/same-numbers
    python benchmarks/same_numbers.py --compare benchmarks/results/same-numbers --json
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

SINGLE_THREADED = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"

#: Columns that measure time, not learning; they are never compared.
TIMING_COLUMNS = frozenset({"wall_s", "steps_per_s"})

SHORT = "--eval-every 1000 --eval-episodes 2 --no-tensorboard --no-progress"

#: Case name -> ``rankgame`` arguments (the output folder is added).
CASES: dict[str, str] = {
    "pal-auto": f"train --env Hopper-v5 --method rank-pal-auto --steps 4000 {SHORT}",
    "ral-auto-lfd": f"train --env Hopper-v5 --method rank-ral-auto --setting lfd --steps 4000 {SHORT}",
    "pal-pref-noise": f"train --env Hopper-v5 --method rank-pal-pref --pref-noise 0.2 --steps 3000 {SHORT}",
    "imit-ral": f"train --env Hopper-v5 --method imit-ral --steps 3000 {SHORT}",
    "ral-switch": (
        "train --env Hopper-v5 --method rank-ral-auto --switch-at 2000 --switch-env rankgame/HopperBackward-v5 "
        f"--steps 4000 {SHORT}"
    ),
    "pal-tuned": f"train --env Hopper-v5 --method rank-pal-auto --recipe tuned --steps 3000 {SHORT}",
    "vanilla-ablation": (
        "train --env Hopper-v5 --method rank-pal-vanilla --reward.spectral-norm --reward.budget passes "
        f"--reward.budget-rows all --steps 3000 {SHORT}"
    ),
    "state-mixup": f"train --env Hopper-v5 --method rank-pal-auto --mixup state --steps 3000 {SHORT}",
    "expert": (
        "expert --env Hopper-v5 --steps 3000 --eval-every 1000 --eval-episodes 2 --trajectories 2 "
        "--random-episodes 2 --no-tensorboard --no-progress"
    ),
}


def run_case(args: str, out: Path, core: int) -> None:
    """Run ``rankgame ARGS --out OUT`` single-threaded on one core; a failure ends the script."""
    env = {**os.environ, "XLA_FLAGS": SINGLE_THREADED}
    command = ["taskset", "-c", str(core), sys.executable, "-m", "rankgame", *shlex.split(args), "--out", str(out)]
    result = subprocess.run(command, env=env, capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"rankgame {args} failed: {result.stderr.strip().splitlines()[-1:]}")


def read_values(path: Path) -> list[dict[str, str]]:
    """The rows of a metrics.csv without its timing columns."""
    with path.open(newline="") as handle:
        return [{k: v for k, v in row.items() if k not in TIMING_COLUMNS} for row in csv.DictReader(handle)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--record", type=Path, help="write each case's metrics.csv under DIR/CASE")
    mode.add_argument("--compare", type=Path, help="compare each case against DIR/CASE/metrics.csv")
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--core", type=int, default=0, help="CPU core to pin the runs to")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    results = {}
    for name in args.cases:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / name
            run_case(CASES[name], out, args.core)
            if args.record is not None:
                target = args.record / name
                target.mkdir(parents=True, exist_ok=True)
                (target / "metrics.csv").write_bytes((out / "metrics.csv").read_bytes())
                (target / "command.txt").write_text(f"rankgame {CASES[name]}\n")
                results[name] = "recorded"
                continue
            before, after = read_values(args.compare / name / "metrics.csv"), read_values(out / "metrics.csv")
            shared = [{k: row[k] for k in before[0].keys() & row.keys()} for row in after]
            same = len(before) == len(after) and all(
                {k: b[k] for k in s} == s for b, s in zip(before, shared, strict=True)
            )
            results[name] = "identical" if same else "DIFFERENT"
    print(json.dumps(results) if args.json else "\n".join(f"{k:>18}: {v}" for k, v in results.items()))
    if any(value == "DIFFERENT" for value in results.values()):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
