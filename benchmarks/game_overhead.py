"""Wall-clock overhead of the ranking game over plain SAC with the same settings, measured in one run.

Runs RANK-PAL(auto) (reward fitting, mixup, absorbing-state bookkeeping and periodic evaluation
included) and then plain SAC on the environment reward, for the same number of environment steps
and the same SAC configuration, and reports env-steps/s of each and the overhead fraction
``1 - game_rate / sac_rate``. The first ``warmup`` steps (random actions, compilation) are excluded.

    python benchmarks/game_overhead.py --env Hopper-v5 --steps 20000 --json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path
from typing import Any

from rankgame.config import TrainConfig
from rankgame.envs.make import make_env
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import sac_preset
from rankgame.training import build_trainer


def time_game(cfg: TrainConfig, warmup: int) -> float:
    """Env-steps/s of ``cfg.method``'s trainer after ``warmup`` steps (same work as ``rankgame train``,
    evaluations every ``cfg.eval_every`` steps included)."""
    game, _ = build_trainer(cfg)
    start = None
    for step in range(1, cfg.steps + 1):
        if step == warmup + 1:
            start = time.perf_counter()
        game.step(step)
        if step % cfg.eval_every == 0:
            game.evaluate()
    assert start is not None
    return (cfg.steps - warmup) / (time.perf_counter() - start)


def time_learner(learner: Any, steps: int, warmup: int) -> float:
    """Env-steps/s of a policy player (``env_step`` then ``maybe_update``) on the environment reward,
    over ``steps`` steps after the first ``warmup``."""
    start = None
    for step in range(1, steps + 1):
        if step == warmup + 1:
            start = time.perf_counter()
        learner.env_step()
        learner.maybe_update()
    assert start is not None
    return (steps - warmup) / (time.perf_counter() - start)


def time_sac(cfg: TrainConfig, warmup: int) -> float:
    """Env-steps/s of plain SAC on the environment reward with the same SAC settings."""
    return time_learner(SACLearner(make_env(cfg.env), cfg.sac, cfg.seed), cfg.steps, warmup)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="Hopper-v5")
    parser.add_argument("--method", default="rank-pal-auto")
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--warmup", type=int, default=2_000)
    parser.add_argument("--preset", default="paper")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cfg = TrainConfig(
            env=args.env, method=args.method, steps=args.steps, out=Path(tmp), sac=sac_preset(args.preset)
        )
        game_rate = time_game(cfg, args.warmup)
        sac_rate = time_sac(dataclasses.replace(cfg), args.warmup)
    result = {
        "env": args.env,
        "method": args.method,
        "timed_steps": args.steps - args.warmup,
        "game_steps_per_s": round(game_rate, 1),
        "sac_steps_per_s": round(sac_rate, 1),
        "overhead_fraction": round(1.0 - game_rate / sac_rate, 3),
    }
    print(json.dumps(result) if args.json else "\n".join(f"{k:>18}: {v}" for k, v in result.items()))


if __name__ == "__main__":
    main()
