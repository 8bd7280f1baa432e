"""Normalized score of ranking-game methods at fixed step budgets, over seeds and tasks.

Runs ``rankgame train`` for every (env, method, seed) not already finished under ``--root`` as a local
``rankgame sweep`` (Ray Tune: ``--cores`` single-threaded runs at once, the fastest way to use a
small machine; a run whose worker dies resumes from its checkpoint), then prints
the mean and standard deviation across seeds of the normalized score at each checkpoint step
(``--at``), as JSON and as a Markdown table, beside the authors' released curve of the same method.
The authors' curves are moving averages over 20 evaluations, one every 1000 steps (see
``PUBLISHED``), so the table also gives each run's mean over the evaluations within the last
``--window`` steps up to the checkpoint (by default 20k: the evaluations at 90k and 100k for 100k).

Each finished run's ``metrics.csv`` and ``config.json`` are copied to ``--archive`` (by default
``benchmarks/results/sample-efficiency``, kept in the repository), so the table can be rebuilt, and
runs are not repeated, without the run folders (which hold large checkpoints).

    python benchmarks/sample_efficiency.py --envs Hopper-v5 HalfCheetah-v5 Walker2d-v5 \
        --methods rank-pal-auto rank-ral-auto --seeds 0 1 2 --steps 300000 --root runs/sample-eff
    python benchmarks/sample_efficiency.py --summarize-only --root runs/sample-eff ...

A variant of the defaults gets its own ``--root`` and ``--archive`` and passes its options with
``--train-args``, e.g. ``--train-args "--reward.lr 1e-4" --root runs/se-lr
--archive benchmarks/results/sample-efficiency-reward-lr-1e-4``.
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from rankgame.data.published import RELEASED_CURVES, TABLE1
from rankgame.envs.variants import OBS_PREFIX_VARIANTS
from rankgame.sweep import Trial, check_trials, launch_trials

#: Authors' released curves (see :mod:`rankgame.data.published`).
PUBLISHED = {
    method: {env: dict(points) for env, points in curves.items()} for method, curves in RELEASED_CURVES.items()
}
# The variants without contact forces are observed as the authors' gym -v2 tasks were: same figures.
for _curves in PUBLISHED.values():
    _curves.update({variant: _curves[source] for variant, (source, _) in OBS_PREFIX_VARIANTS.items()})


#: How to pass ``--train-args`` a value that argparse would take for an option of its own.
TRAIN_ARGS_NOTE = "write --train-args=--sac.learn-alpha (with '=') when the value is a single word starting with '-'"


def env_folder_name(env: str) -> str:
    """``env`` as one folder name: ``rankgame/Door-v0`` becomes ``rankgame__Door-v0``."""
    return env.replace("/", "__")


def run_dir(root: Path, env: str, method: str, seed: int) -> Path:
    return root / f"{env_folder_name(env)}__{method}__s{seed}"


def archive_if_finished(out: Path, archived: Path, steps: int) -> None:
    """Copy the ``metrics.csv`` and ``config.json`` of a run that logged its evaluation after ``steps``
    environment steps to ``archived`` (a shorter run is continued by :func:`run_jobs`, not archived)."""
    finished = max(read_scores(out, out), default=0) >= steps
    if finished and not (archived / "metrics.csv").exists():
        archived.mkdir(parents=True, exist_ok=True)
        for name in ("metrics.csv", "config.json"):
            shutil.copyfile(out / name, archived / name)


@dataclass(frozen=True)
class Job:
    """One ``rankgame train`` run: where it writes, where its results are archived, and what it trains."""

    out: Path
    archived: Path
    env: str
    method: str
    seed: int
    train_args: str = ""

    def train_argv(self, steps: int) -> list[str]:
        """The ``rankgame train`` options of the run (its folder as an absolute path)."""
        argv = ["--env", self.env, "--method", self.method, "--seed", str(self.seed), "--steps", str(steps)]
        return [*argv, "--out", str(self.out.resolve()), "--no-progress", *shlex.split(self.train_args)]

    def command(self, steps: int) -> list[str]:
        """The command line a user would type for the run (``--resume`` once its folder holds metrics)."""
        resume = ["--resume"] if (self.out / "metrics.csv").exists() else []
        return ["rankgame", "train", *self.train_argv(steps), *resume]


def launch_all(args: argparse.Namespace) -> None:
    """Run the missing trainings of ``--envs`` x ``--methods`` x ``--seeds`` as a local sweep."""
    jobs = [
        Job(
            run_dir(args.root, env, method, seed),
            run_dir(args.archive, env, method, seed),
            env,
            method,
            seed,
            args.train_args,
        )
        for env in args.envs
        for method in args.methods
        for seed in args.seeds
    ]
    run_jobs(jobs, args.steps, args.root, args.cores)


def run_jobs(jobs: list[Job], steps: int, root: Path, cores: int | None = None) -> None:
    """Run every job not yet archived to ``steps`` on a local Ray Tune sweep (:func:`rankgame.sweep.launch_trials`:
    ``cores`` single-threaded trials at once, each resuming its folder if it holds a run), then archive
    the finished ones; Ray keeps its state in ``root/.ray``."""
    for job in jobs:
        archive_if_finished(job.out, job.archived, steps)
    todo = [job for job in jobs if not (job.archived / "metrics.csv").exists()]
    if not todo:
        return
    trials = [Trial(str(job.out), tuple(job.train_argv(steps)), steps) for job in todo]
    check_trials(trials)
    failed = launch_trials(trials, str((root / ".ray").resolve()), cores=cores)
    for job in todo:
        archive_if_finished(job.out, job.archived, steps)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)


def logged_folder(out: Path, archived: Path) -> Path | None:
    """Where a run's ``metrics.csv`` is read from: its run folder, else its archived copy; None if neither."""
    return next((folder for folder in (out, archived) if (folder / "metrics.csv").exists()), None)


class Metric(NamedTuple):
    """A score a summary can read from ``metrics.csv``: its column, the factor to the reported scale, and
    how tables name it."""

    column: str
    factor: float
    label: str


#: The scores a summary can read, by name.
METRICS: dict[str, Metric] = {
    "normalized": Metric("normalized_score", 1.0, "normalized score"),
    "success": Metric("eval_success", 100.0, "success rate (%)"),
}


def read_scores(out: Path, archived: Path, metric: str = "normalized") -> dict[int, float]:
    """A run's score by evaluation step (its folder, else its archived copy; empty if neither): the
    normalized score, or with ``metric="success"`` the share of successful evaluation episodes in percent."""
    folder = logged_folder(out, archived)
    if folder is None:
        return {}
    column, factor, _ = METRICS[metric]
    with (folder / "metrics.csv").open() as handle:
        return {int(row["env_steps"]): factor * float(row[column]) for row in csv.DictReader(handle)}


RunScores = dict[tuple[str, str, int], dict[int, float]]


def read_all_scores(args: argparse.Namespace) -> RunScores:
    """:func:`read_scores` of every (env, method, seed) asked for."""
    return {
        (env, method, seed): read_scores(
            run_dir(args.root, env, method, seed), run_dir(args.archive, env, method, seed)
        )
        for env in args.envs
        for method in args.methods
        for seed in args.seeds
    }


def window_mean(scores: dict[int, float], step: int, window: int) -> float:
    """Mean score of the evaluations in ``(step - window, step]``; the run must have one at ``step``."""
    return float(np.mean([score for at, score in scores.items() if step - window < at <= step]))


def mean_and_std(values: list[float]) -> tuple[float | None, float | None]:
    """Mean and sample standard deviation (n - 1) rounded to 0.1; None for what n does not define."""
    if not values:
        return None, None
    std = round(float(np.std(values, ddof=1)), 1) if len(values) > 1 else None
    return round(float(np.mean(values)), 1), std


def summarize(args: argparse.Namespace, all_scores: RunScores) -> list[dict]:
    """Mean and standard deviation over the seeds of the score at each ``--at`` step, and of each
    seed's mean over the evaluations in the ``--window`` steps up to it."""
    table = []
    for env in args.envs:
        for method in args.methods:
            runs = [all_scores[env, method, seed] for seed in args.seeds]
            for step in args.at:
                finished = [run for run in runs if step in run]
                mean, std = mean_and_std([run[step] for run in finished])
                window, window_std = mean_and_std([window_mean(run, step, args.window) for run in finished])
                table.append(
                    {
                        "env": env,
                        "method": method,
                        "step": step,
                        "seeds": len(finished),
                        "mean": mean,
                        "std": std,
                        "window_mean": window,
                        "window_std": window_std,
                        "published": PUBLISHED.get(method, {}).get(env, {}).get(step),
                        "paper_2m": TABLE1.get(method, {}).get(env),
                    }
                )
    return table


def _pm(mean: float | None, std: float | None) -> str:
    """``mean ± std`` as table text: ``-`` without a mean, the mean alone without a std (one seed)."""
    if mean is None:
        return "-"
    return f"{mean}" if std is None else f"{mean} ± {std}"


def curve_mean(scores: dict[int, float], steps: int) -> float:
    """Mean of a run's evaluations up to ``steps``: the area under its learning curve, steadier than any
    single evaluation."""
    return float(np.mean([score for step, score in scores.items() if step <= steps]))


def run_profile(scores: dict[int, float], steps: int, threshold: float) -> dict | None:
    """How a run reached and held the imitation: the first evaluation step whose score reaches
    ``threshold`` (None if none), the median, minimum and maximum of the evaluations in the second
    half of the run (how steady it stays) and the :func:`curve_mean`; read up to ``steps``. None for a
    run that has not reached ``steps``."""
    if max(scores, default=0) < steps:
        return None
    within = {step: score for step, score in sorted(scores.items()) if step <= steps}
    late = [score for step, score in within.items() if step >= steps // 2]
    reached = [step for step, score in within.items() if score >= threshold]
    return {
        "first_step_at_threshold": reached[0] if reached else None,
        "late_median": round(float(np.median(late)), 1),
        "late_min": round(min(late), 1),
        "late_max": round(max(late), 1),
        "curve_mean": round(curve_mean(scores, steps), 1),
    }


def first_step_text(profile: dict) -> str:
    """A profile's first step at the threshold as table text: ``"90k"`` or ``"never"``."""
    first = profile["first_step_at_threshold"]
    return "never" if first is None else f"{first // 1000}k"


def spread_text(profile: dict) -> str:
    """A profile's median / minimum / maximum over the second half of the run as table text."""
    return f"{profile['late_median']} / {profile['late_min']} / {profile['late_max']}"


def per_run(args: argparse.Namespace, all_scores: RunScores) -> list[dict]:
    """:func:`run_profile` of every run that reached ``--steps``, with its env, method and seed."""
    rows = []
    for (env, method, seed), scores in all_scores.items():
        profile = run_profile(scores, args.steps, args.threshold)
        if profile is not None:
            rows.append({"env": env, "method": method, "seed": seed, **profile})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", nargs="+", default=["Hopper-v5", "HalfCheetah-v5", "Walker2d-v5"])
    parser.add_argument("--methods", nargs="+", default=["rank-pal-auto", "rank-ral-auto"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--at", nargs="+", type=int, default=[100_000, 300_000])
    parser.add_argument(
        "--window", type=int, default=20_000, help="steps up to each --at whose evaluations are also averaged"
    )
    parser.add_argument("--threshold", type=float, default=80.0, help="score whose first crossing is reported")
    parser.add_argument("--root", type=Path, default=Path("runs/sample-efficiency"))
    parser.add_argument("--archive", type=Path, default=Path("benchmarks/results/sample-efficiency"))
    parser.add_argument("--cores", type=int, help="runs at once (default: the machine's cores)")
    parser.add_argument(
        "--train-args",
        default="",
        help=f"further options for every `rankgame train`, e.g. '--reward.lr 1e-4'; {TRAIN_ARGS_NOTE}",
    )
    parser.add_argument("--summarize-only", action="store_true")
    args = parser.parse_args()
    if not args.summarize_only:
        launch_all(args)
    all_scores = read_all_scores(args)
    table, runs = summarize(args, all_scores), per_run(args, all_scores)
    print(json.dumps({"at_steps": table, "runs": runs}))
    window = f"mean over the last {args.window // 1000}k steps"
    print(
        f"\n| env | method | steps | seeds | normalized score (mean ± sample std) | {window} "
        "| authors' curve, same step | paper, Table 1 at 2M |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in table:
        paper = "-" if row["paper_2m"] is None else f"{row['paper_2m'][0]} ± {row['paper_2m'][1]}"
        print(
            f"| {row['env']} | {row['method']} | {row['step'] // 1000}k | {row['seeds']} "
            f"| {_pm(row['mean'], row['std'])} | {_pm(row['window_mean'], row['window_std'])} "
            f"| {row['published'] or '-'} | {paper} |"
        )
    half = f"{args.steps // 2000}k-{args.steps // 1000}k"
    print(
        f"\n| env | method | seed | first step at >= {args.threshold:g} | median / min / max over {half} "
        f"| mean of the evaluations to {args.steps // 1000}k |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for row in runs:
        print(
            f"| {row['env']} | {row['method']} | {row['seed']} | {first_step_text(row)} | {spread_text(row)} "
            f"| {row['curve_mean']} |"
        )


if __name__ == "__main__":
    main()
