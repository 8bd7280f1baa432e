"""The policy a run hands over: its selected policy against its final one, on fresh episodes.

A game run keeps two actors: ``policy.msgpack`` (its last evaluation) and ``selected_policy.msgpack``
(the evaluation its learned reward rated best, :mod:`rankgame.game.selection`). The in-run score of the
selected evaluation comes from the same episodes the criterion read, so this script scores both
actors again on ``--episodes`` episodes reset from ``--seed`` (apart from the runs' own evaluation
and training resets) and prints, as JSON:

* per run: its final and selected evaluations in ``metrics.csv`` (step, score, criterion) and the
  fresh scores of both actors;
* over the runs: n, mean and sample standard deviation (n - 1) of each fresh score, and how many of
  the actors score below ``--below`` (50): a collapsed policy handed to the user;
* over all the runs' evaluations: the Spearman rank correlation between the criterion and the
  normalized score (how well the learned reward alone orders the policies by their true score).

``--plot FIG`` also draws every evaluation's criterion against its normalized score, each run's
selected evaluation starred and its last one ringed (matplotlib, the ``plot`` extra). Example (the
held-out runs of the notebook's selection study)::

    python benchmarks/selection.py benchmarks/results/selection-heldout-hopper-pal/*s10* --episodes 20 \\
        --out benchmarks/results/selection-heldout-hopper-pal/fresh.json --plot docs/img/selection.png
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from script_io import emit

from rankgame.errors import RankGameError
from rankgame.evaluate import EvaluateConfig, evaluate_policy
from rankgame.game.selection import SELECTED_POLICY_NAME, SELECTION_COLUMN, selected_evaluation
from rankgame.plot import pyplot, read_curve
from rankgame.run import POLICY_NAME

#: First reset seed of the fresh episodes (the runs evaluate from seed + 10000, seeds 0-999 here).
FRESH_SEED = 50_000


def score_run(folder: Path, episodes: int, seed: int) -> dict[str, Any]:
    """One run's final and selected evaluations and the fresh scores of both actors."""
    selected = selected_evaluation(folder)
    if selected is None or not (folder / SELECTED_POLICY_NAME).is_file():
        raise RankGameError(f"{folder}: no selected policy (a game run of this version keeps one)")
    steps, scores = read_curve(folder, "normalized_score")
    recorded = json.loads((folder / "config.json").read_text()).get("expert")
    expert = Path(recorded) if recorded and Path(recorded).is_file() else None  # else the task's shipped data

    def fresh(name: str) -> float:
        config = EvaluateConfig(policy=folder / name, episodes=episodes, seed=seed, expert=expert)
        result = evaluate_policy(config)
        if result["normalized_score"] is None:
            raise RankGameError(f"{folder / name}: no shipped expert data to normalize its score")
        return float(result["normalized_score"])

    return {
        "run": str(folder),
        "final": {"env_steps": steps[-1], "normalized_score": scores[-1], "fresh_score": fresh(POLICY_NAME)},
        "selected": {
            "env_steps": selected.env_steps,
            "learned_return": selected.learned_return,
            "normalized_score": selected.normalized_score,
            "fresh_score": fresh(SELECTED_POLICY_NAME),
        },
    }


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rank correlation of ``x (N,)`` and ``y (N,)`` (average ranks for ties)."""

    def ranks(values: np.ndarray) -> np.ndarray:
        order = np.argsort(values, kind="stable")
        ranked = np.empty(len(values))
        ranked[order] = np.arange(len(values), dtype=float)
        for value in np.unique(values):  # ties share their mean rank
            ranked[values == value] = ranked[values == value].mean()
        return ranked

    return float(np.corrcoef(ranks(x), ranks(y))[0, 1])


def criterion_and_scores(folders: list[Path]) -> tuple[np.ndarray, np.ndarray]:
    """The criterion and the normalized score ``(N,)`` of every evaluation of the runs where both exist."""
    pairs = []
    for folder in folders:
        criterion = dict(zip(*read_curve(folder, SELECTION_COLUMN), strict=True))
        scores = dict(zip(*read_curve(folder, "normalized_score"), strict=True))
        pairs += [(value, scores[step]) for step, value in criterion.items() if step in scores and np.isfinite(value)]
    return np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])


def plot_criterion(folders: list[Path], runs: list[dict[str, Any]], out: Path) -> None:
    """Criterion against normalized score for every evaluation of ``folders``; selected starred, last ringed."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for folder, run in zip(folders, runs, strict=True):
        x, y = criterion_and_scores([folder])
        dots = ax.plot(x, y, "o", ms=3, alpha=0.6, label=folder.name)[0]
        steps, criterion = read_curve(folder, SELECTION_COLUMN)
        last = dict(zip(steps, criterion, strict=True)).get(run["final"]["env_steps"], np.nan)
        ax.plot(
            [run["selected"]["learned_return"]],
            [run["selected"]["normalized_score"]],
            "*",
            ms=14,
            color=dots.get_color(),
            markeredgecolor="k",
        )
        ax.plot([last], [run["final"]["normalized_score"]], "o", ms=11, mfc="none", color=dots.get_color())
    ax.axhline(50, color="r", lw=0.6, ls="--")
    ax.set_xlabel("learned return / expert's (selection/learned_return)")
    ax.set_ylabel("normalized score (true reward)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


def aggregate(runs: list[dict[str, Any]], below: float) -> dict[str, Any]:
    """n, mean, sample std (n - 1) and the count below ``below`` of the fresh scores of each actor."""
    summary: dict[str, Any] = {"n": len(runs)}
    for actor in ("final", "selected"):
        fresh = np.array([run[actor]["fresh_score"] for run in runs])
        summary[actor] = {
            "mean": float(fresh.mean()),
            "std": float(fresh.std(ddof=1)) if len(fresh) > 1 else None,
            "below": int((fresh < below).sum()),
        }
    return summary


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="game run folders")
    parser.add_argument("--episodes", type=int, default=20, help="fresh episodes per actor")
    parser.add_argument("--seed", type=int, default=FRESH_SEED, help="reset seed of the first fresh episode")
    parser.add_argument("--below", type=float, default=50.0, help="a score below this is a collapsed policy")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    parser.add_argument("--plot", type=Path, help="also draw the criterion against the score here (PNG)")
    args = parser.parse_args(argv)
    try:
        if args.episodes <= 0:
            raise RankGameError(f"--episodes must be positive (got {args.episodes})")
        folders = [run for run in args.runs if not run.is_file()]  # a shell glob may list a result file
        if not folders:
            raise RankGameError("no run folders given")
        if args.plot is not None:
            pyplot()  # a missing plot extra fails here, before any work
        runs = [score_run(folder, args.episodes, args.seed) for folder in folders]
    except RankGameError as exc:
        print(f"selection.py: {exc}", file=sys.stderr)
        return 1
    result = {
        "command": "python benchmarks/selection.py " + " ".join(argv),
        "episodes": args.episodes,
        "seed": args.seed,
        "aggregate": aggregate(runs, args.below),
        "criterion_score_spearman": spearman(*criterion_and_scores(folders)),
        "runs": runs,
    }
    if args.plot is not None:
        plot_criterion(folders, runs, args.plot)
    emit(result, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
