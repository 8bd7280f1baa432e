"""How stable runs stay once they imitate well: collapses after first reaching expert level.

For every run folder under the given roots (a folder holding ``metrics.csv``, and ``config.json``
or a name that starts with its task id and a seed, ``Walker2d-v5-s0``) it reads the normalized
score of each evaluation; runs of ``rankgame expert`` (SAC on the true reward, the reference) have
their ``eval_return`` normalized with the shipped expert data of their task. Runs are grouped by
their folder (the root, or its first subfolder when run folders lie deeper: one folder per
variant), task and method, and each group reports:

* ``runs``, and ``reached``: how many runs had an evaluation at ``--reach`` (80) or more;
* ``after`` and ``collapsed``: the evaluations after a run first reached ``--reach``, and how many of
  them fell below ``--below`` (50); ``share`` is collapsed / after over the group;
* ``final`` and ``best``: the mean over runs of the last and of the best evaluation.

Each run's own figures are printed with ``--per-run``. The figures are read from ``metrics.csv``;
how many episodes each evaluation averaged is the run's ``eval_episodes`` (5 for the archived runs).

    python benchmarks/stability.py benchmarks/results/sample-efficiency benchmarks/results/hopper-early \\
        benchmarks/results/walker-sac-true-reward --json
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from dataclasses import dataclass
from pathlib import Path

from rankgame.report import SAC_TRUE_REWARD, collapse_counts, true_reward_curve


@dataclass(frozen=True)
class RunScores:
    """The normalized score of each evaluation of one run, in step order."""

    group: tuple[str, str, str]  # (root, env, method)
    name: str
    steps: tuple[int, ...]
    scores: tuple[float, ...]


def run_config(folder: Path) -> dict:
    """The run's ``config.json``; an archived expert run without one is named after its task
    (``Walker2d-v5-s0``), whose id is then read from the folder name."""
    if (folder / "config.json").is_file():
        return json.loads((folder / "config.json").read_text())
    from rankgame.data.experts import shipped_envs

    tasks = [env for env in shipped_envs() if folder.name.startswith(env.replace("/", "__") + "-s")]
    if not tasks:
        raise ValueError(f"{folder} has no config.json and its name does not start with a task id")
    return {"env": max(tasks, key=len).replace("__", "/")}


def read_run(folder: Path, root: Path) -> RunScores | None:
    """A run's scores, or None for a folder that is not a finished evaluation log (no score column)."""
    config = run_config(folder)
    with (folder / "metrics.csv").open(newline="") as handle:
        rows = [row for row in csv.DictReader(handle) if row.get("eval_return")]
    if not rows:
        return None
    if "normalized_score" in rows[0]:
        method, scores = config["method"], [float(row["normalized_score"]) for row in rows]
    else:  # a rankgame expert run: its true return normalized with the shipped expert data
        method, scores = SAC_TRUE_REWARD, true_reward_curve(folder, config["env"])[1]
    steps = tuple(int(row["env_steps"]) for row in rows)
    relative = folder.relative_to(root)
    variant = root.name if len(relative.parts) < 2 else f"{root.name}/{relative.parts[0]}"
    return RunScores((variant, config["env"], method), str(relative), steps, tuple(scores))


def summarize(runs: list[RunScores], reach: float, below: float) -> list[dict]:
    """One row per group (see the module docstring)."""
    groups: dict[tuple[str, str, str], list[RunScores]] = {}
    for run in runs:
        groups.setdefault(run.group, []).append(run)
    rows = []
    for (root, env, method), members in sorted(groups.items()):
        counts = [c for c in (collapse_counts(r.scores, reach, below) for r in members) if c is not None]
        after, collapsed = sum(c[0] for c in counts), sum(c[1] for c in counts)
        rows.append(
            {
                "root": root,
                "env": env,
                "method": method,
                "runs": len(members),
                "reached": len(counts),
                "after": after,
                "collapsed": collapsed,
                "share": collapsed / after if after else None,
                "final": sum(r.scores[-1] for r in members) / len(members),
                "best": sum(max(r.scores) for r in members) / len(members),
                "last_step": min(r.steps[-1] for r in members),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("roots", nargs="+", type=Path, help="folders searched for run folders")
    parser.add_argument("--reach", type=float, default=80.0, help="the score a run must reach first (default: 80)")
    parser.add_argument("--below", type=float, default=50.0, help="a later score below this is a collapse (50)")
    parser.add_argument("--per-run", action="store_true", help="also print every run's own counts")
    parser.add_argument("--json", action="store_true", help="print JSON lines instead of a Markdown table")
    args = parser.parse_args()
    runs = []
    for root in args.roots:
        if not root.is_dir():
            sys.exit(f"stability.py: error: {root} is not a folder")
        for metrics in sorted(root.rglob("metrics.csv")):
            try:
                run = read_run(metrics.parent, root)
            except (ValueError, KeyError) as exc:
                sys.exit(f"stability.py: error: {exc}")
            if run is not None:
                runs.append(run)
    if not runs:
        sys.exit("stability.py: error: no run folders (with a metrics.csv) under the given roots")
    rows = summarize(runs, args.reach, args.below)
    if args.per_run:
        for run in runs:
            print(
                json.dumps(
                    {"run": f"{run.group[0]}/{run.name}", "counts": collapse_counts(run.scores, args.reach, args.below)}
                )
            )
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return
    print(
        f"| root | task | method | runs | reached {args.reach:g} | later evaluations | below {args.below:g} "
        "| share | final | best | steps |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        share = "-" if r["share"] is None else f"{100 * r['share']:.1f}%"
        print(
            f"| {r['root']} | {r['env']} | {r['method']} | {r['runs']} | {r['reached']} | {r['after']} | "
            f"{r['collapsed']} | {share} | {r['final']:.1f} | {r['best']:.1f} | {r['last_step']} |"
        )


if __name__ == "__main__":
    main()
