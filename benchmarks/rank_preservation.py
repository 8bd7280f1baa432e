"""How often the reward that minimizes SL_k keeps the ranking it was fit to (the paper, App. D, "On the
rank preserving nature of SL_k").

On a finite state space of ``|S|`` states, ``n`` behaviors ``rho_0 <= rho_1 <= ... <= rho_{n-1}`` are
state visitations drawn uniformly from the simplex (Dirichlet(1, ..., 1)), each regressed to a target
``k_0 <= ... <= k_{n-1}`` in ``[0, k]``. A tabular reward ``R`` minimizes

    SL_k(R) = 1/n sum_i E_{s ~ rho_i} (R(s) - k_i)^2                      (App. B.1, Eq. 8)

in closed form, state by state: ``R*(s) = sum_i rho_i(s) k_i / sum_i rho_i(s)``, the targets averaged
with the visitation of each behavior at ``s`` as weights (:func:`sl_k_minimizer`). The ranking is kept
for a pair ``i < j`` when ``E_{rho_i} R* < E_{rho_j} R*``; a trial's *rank consistency* is the share of
its ``n (n - 1) / 2`` pairs kept (:func:`rank_consistency`). The paper draws the targets uniformly and
sorts them (``--targets uniform``, the default); ``--targets exp`` uses the targets of the package's
default exp schedule at evenly spaced positions instead.

Prints JSON: for every ``|S|`` x ``n`` cell, n trials, the mean consistency and its 95% bootstrap
confidence interval, and the share of trials that keep every pair. ``--plot FIG`` draws the paper's
two panels: consistency against ``|S|`` (one line per ``n``) and against ``n`` (one line per ``|S|``).
Example (the notebook's figure)::

    python benchmarks/rank_preservation.py --out benchmarks/results/rank-preservation/uniform.json \\
        --plot docs/img/rank_preservation.png
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
from script_io import emit, refused

from rankgame.errors import RankGameError
from rankgame.game.rankings import RankingsConfig
from rankgame.plot import pyplot

#: State-space sizes and numbers of ranked behaviors of the default grid.
STATES = (2, 5, 10, 20, 50, 100, 200, 500, 1000)
BEHAVIORS = (2, 3, 5, 10, 20, 50)


def sl_k_minimizer(visitations: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """The tabular reward ``(..., |S|)`` that minimizes SL_k: ``R*(s) = sum_i rho_i(s) k_i / sum_i rho_i(s)``.

    Args:
        visitations: ``(..., n, |S|)`` state visitations, each row a distribution over the states.
        targets: ``(..., n)`` regression target of each behavior.
    """
    weights = visitations.sum(axis=-2)
    return np.einsum("...is,...i->...s", visitations, targets) / weights


def rank_consistency(visitations: np.ndarray, reward: np.ndarray) -> np.ndarray:
    """Share ``(...)`` of the pairs ``i < j`` of behaviors, ranked in order, whose expected rewards keep the
    order: ``E_{rho_i} R < E_{rho_j} R``; ``visitations (..., n, |S|)``, ``reward (..., |S|)``, n >= 2."""
    returns = np.einsum("...is,...s->...i", visitations, reward)
    n = returns.shape[-1]
    upper = np.triu(np.ones((n, n), bool), k=1)
    kept = returns[..., :, None] < returns[..., None, :]
    return (kept & upper).sum(axis=(-2, -1)) / upper.sum()


def draw_targets(rng: np.random.Generator, trials: int, n: int, kind: str, k: float) -> np.ndarray:
    """Targets ``(trials, n)`` in ``[0, k]``, non-decreasing: the paper's sorted uniform draws with the ends
    pinned to 0 and k (``uniform``), or the default exp schedule at ``n`` evenly spaced positions (``exp``)."""
    if kind == "exp":
        config = RankingsConfig(k=k)
        return np.broadcast_to(config.targets(np.linspace(0.0, 1.0, n)), (trials, n)).copy()
    inner = np.sort(rng.uniform(0.0, k, size=(trials, n - 2)), axis=-1)
    return np.concatenate([np.zeros((trials, 1)), inner, np.full((trials, 1), k)], axis=-1)


def bootstrap_mean_ci(values: np.ndarray, rng: np.random.Generator, n_boot: int = 2000) -> tuple[float, float]:
    """95% percentile bootstrap interval of the mean of ``values (m,)``."""
    means = rng.choice(values, size=(n_boot, len(values))).mean(axis=1)
    low, high = np.quantile(means, [0.025, 0.975])
    return float(low), float(high)


def study(
    states: tuple[int, ...], behaviors: tuple[int, ...], trials: int, targets: str, k: float, seed: int
) -> list[dict[str, Any]]:
    """Every ``|S|`` x ``n`` cell of the study (see the module docstring), in that order."""
    rng = np.random.default_rng(seed)
    cells = []
    for size in states:
        for n in behaviors:
            visitations = rng.dirichlet(np.ones(size), size=(trials, n))
            goals = draw_targets(rng, trials, n, targets, k)
            consistency = rank_consistency(visitations, sl_k_minimizer(visitations, goals))
            low, high = bootstrap_mean_ci(consistency, rng)
            cells.append(
                {
                    "states": size,
                    "behaviors": n,
                    "pairs": n * (n - 1) // 2,
                    "trials": trials,
                    "mean_consistency": float(consistency.mean()),
                    "ci95": [low, high],
                    "all_pairs_kept": float((consistency == 1.0).mean()),
                }
            )
    return cells


def plot_study(cells: list[dict[str, Any]], out: Path) -> None:
    """The two panels of the paper's figure: consistency against ``|S|`` and against ``n``, with 95% CIs."""
    plt = pyplot()
    fig, (by_states, by_behaviors) = plt.subplots(1, 2, figsize=(10, 4))
    for axis, line_key, x_key, label in (
        (by_states, "behaviors", "states", "ranked behaviors n = {}"),
        (by_behaviors, "states", "behaviors", "|S| = {}"),
    ):
        for value in sorted({cell[line_key] for cell in cells}):
            line = sorted((c for c in cells if c[line_key] == value), key=lambda c: c[x_key])
            x = [c[x_key] for c in line]
            axis.plot(x, [c["mean_consistency"] for c in line], "o-", ms=3, label=label.format(value))
            axis.fill_between(x, [c["ci95"][0] for c in line], [c["ci95"][1] for c in line], alpha=0.2)
        axis.set_xscale("log")
        ticks = sorted({cell[x_key] for cell in cells})
        axis.set_xticks(ticks, [str(t) for t in ticks], minor=False)
        axis.set_xticks([], minor=True)
        axis.set_xlabel("number of states |S|" if x_key == "states" else "number of ranked behaviors n")
        axis.set_ylabel("share of pairs kept by the SL_k minimizer")
        axis.legend(fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--states", type=int, nargs="+", default=list(STATES), help="state-space sizes |S|")
    parser.add_argument("--behaviors", type=int, nargs="+", default=list(BEHAVIORS), help="ranked behaviors n")
    parser.add_argument("--trials", type=int, default=1000, help="random rankings per cell")
    parser.add_argument("--targets", choices=("uniform", "exp"), default="uniform", help="how targets are drawn")
    parser.add_argument("--k", type=float, default=10.0, help="the expert's target (the largest)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the visitations and targets")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    parser.add_argument("--plot", type=Path, help="also draw the two panels here (PNG)")
    args = parser.parse_args(argv)
    problems = [
        (min(args.states) < 1, "--states must be positive"),
        (min(args.behaviors) < 2, "--behaviors must be at least 2 (one pair)"),
        (args.trials < 1, "--trials must be positive"),
        (not np.isfinite(args.k) or args.k <= 0, "--k must be positive and finite"),
    ]
    if refused("rank_preservation.py", problems):
        return 1
    try:
        if args.plot is not None:
            pyplot()  # a missing plot extra fails here, before any work
    except RankGameError as exc:
        print(f"rank_preservation.py: {exc}", file=sys.stderr)
        return 1
    cells = study(tuple(args.states), tuple(args.behaviors), args.trials, args.targets, args.k, args.seed)
    result = {"command": "python benchmarks/rank_preservation.py " + " ".join(argv), "cells": cells}
    if args.plot is not None:
        plot_study(cells, args.plot)
    emit(result, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
