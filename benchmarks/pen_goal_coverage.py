"""Which Pen goals a saved policy reaches, against how close each goal is to a demonstrated one.

rankgame/Pen-v0 draws a new target orientation for the pen at every reset, and the observation holds
it (entries 36-38, a unit vector). A policy trained by imitating a few expert trajectories has seen
the expert reach only those trajectories' goals. This script rolls the policy out deterministically
for ``--episodes`` episodes (episode ``i`` reset with ``--seed + i``, as ``rankgame evaluate`` does)
and groups the episodes by the cosine between their goal and the nearest goal among the first
``--expert-trajectories`` trajectories of the expert file, printing per group the number of episodes,
the success rate (mjrl's rule, as in the training log) and the mean return, as JSON and as a table.

    python benchmarks/pen_goal_coverage.py runs/pen/RUN/policy.msgpack --expert-trajectories 10 \\
        --episodes 100 --seed 50000
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from rankgame.data.experts import shipped_expert_path
from rankgame.data.trajectories import load_trajectories
from rankgame.envs.make import make_env
from rankgame.envs.rollout import episode_succeeded, run_episodes
from rankgame.errors import RankGameError
from rankgame.policy.io import load_policy

PEN_ID = "rankgame/Pen-v0"
#: Observation entries of the target orientation in AdroitHandPen-v1 (``desired_orien``).
GOAL_ENTRIES = slice(36, 39)
#: Upper edges of the cosine groups; the first group starts at -1.
COSINE_EDGES = (0.5, 0.8, 0.95, 1.0)


def unit_goals(first_obs: np.ndarray) -> np.ndarray:
    """Target orientations ``(n, 3)`` of first observations ``(n, obs_dim)``, scaled to unit length."""
    goals = first_obs[:, GOAL_ENTRIES]
    return goals / np.linalg.norm(goals, axis=1, keepdims=True)


def nearest_cosine(goals: np.ndarray, demonstrated: np.ndarray) -> np.ndarray:
    """Cosine ``(n,)`` between each unit goal ``(n, 3)`` and its nearest demonstrated unit goal ``(m, 3)``."""
    return (goals @ demonstrated.T).max(axis=1)


def group_by_cosine(cosines: np.ndarray, returns: np.ndarray, successes: np.ndarray) -> list[dict[str, float]]:
    """Episode count, success rate and mean return per cosine group (groups without episodes left out)."""
    rows, low = [], -1.0
    for high in COSINE_EDGES:
        inside = (cosines >= low) & ((cosines < high) if high < 1.0 else (cosines <= high))
        if inside.any():
            rows.append(
                {
                    "cosine_from": low,
                    "cosine_to": high,
                    "episodes": int(inside.sum()),
                    "success_rate": float(successes[inside].mean()),
                    "mean_return": float(returns[inside].mean()),
                }
            )
        low = high
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", type=Path, help="policy.msgpack written by rankgame train on rankgame/Pen-v0")
    parser.add_argument("--expert", type=Path, default=None, help="expert file (default: the shipped Pen data)")
    parser.add_argument("--expert-trajectories", type=int, default=1, help="demonstrated trajectories (the first ones)")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=50_000, help="reset seed of the first episode")
    args = parser.parse_args(argv)
    try:
        saved = load_policy(args.policy)
        if saved.env_id != PEN_ID:
            raise RankGameError(f"{args.policy} was trained on {saved.env_id}, not {PEN_ID}")
        expert = load_trajectories(args.expert or shipped_expert_path(PEN_ID), env_id=PEN_ID)
        if not 1 <= args.expert_trajectories <= len(expert.trajectories):
            raise RankGameError(f"--expert-trajectories must lie in 1..{len(expert.trajectories)}")
        if args.episodes < 1:
            raise RankGameError(f"--episodes must be positive (got {args.episodes})")
        env = make_env(PEN_ID)  # needs the manipulation extra
    except RankGameError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    demonstrated = unit_goals(np.stack([t.obs[0] for t in expert.trajectories[: args.expert_trajectories]]))
    episodes, success_steps = run_episodes(
        env, saved.policy_fn(deterministic=True, seed=args.seed), args.episodes, args.seed
    )
    env.close()
    cosines = nearest_cosine(unit_goals(np.stack([e.obs[0] for e in episodes])), demonstrated)
    returns = np.array([e.ret for e in episodes])
    successes = np.array([episode_succeeded(steps) for steps in success_steps], float)
    groups = group_by_cosine(cosines, returns, successes)
    summary = {
        "policy": str(args.policy),
        "expert_trajectories": args.expert_trajectories,
        "episodes": args.episodes,
        "success_rate": float(successes.mean()),
        "mean_return": float(returns.mean()),
        "groups": groups,
    }
    print(json.dumps(summary))
    print("\n| cosine to the nearest demonstrated goal | episodes | success rate | mean return |")
    print("| --- | --- | --- | --- |")
    for row in groups:
        span = f"{row['cosine_from']:.2f} to {row['cosine_to']:.2f}"
        print(f"| {span} | {row['episodes']} | {row['success_rate']:.0%} | {row['mean_return']:.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
