"""Env-steps/s of every method against plain SAC and plain PPO on the true reward, measured in one run.

Each method trains for ``--steps`` environment steps with its default settings (what ``rankgame train``
does, evaluations every ``--eval-every`` steps included) and is compared with the plain learner of its
policy player on the environment reward, with the same settings, timed in the same process: SAC for
the rank-game methods, DAC, DACfO and T-REX, PPO for GAIL and GAIfO. BCO, which acts with a cloned
policy and fits only at round ends, is compared with SAC, and so is IQ-Learn, which runs with its own
SAC preset (``iq-learn``: batches of 256 agent and 256 expert rows), and OPOLO, whose TD3 player
(400-300 networks, batches of 100, one gradient step per environment step) starts updating after the
warm-up instead of after its 10000 random steps. The first ``--warmup`` steps (random actions,
compilation) are excluded. BC takes no environment steps and is left out.

    python benchmarks/method_throughput.py --env Hopper-v5 --steps 12000 \
        --methods rank-pal-auto dacfo gaifo bco --json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import tempfile
from pathlib import Path

from game_overhead import time_game, time_learner, time_sac

from rankgame.baselines.cloning import CloningConfig
from rankgame.config import TrainConfig
from rankgame.envs.make import make_env
from rankgame.game.methods import METHODS, OWN_TRAINER_METHODS
from rankgame.policy.ppo_learner import PPOLearner
from rankgame.policy.sac import sac_preset
from rankgame.policy.td3 import TD3Config


def time_ppo(cfg: TrainConfig, warmup: int) -> float:
    """Env-steps/s of plain PPO on the environment reward with ``cfg.ppo``."""
    return time_learner(PPOLearner(make_env(cfg.env), cfg.ppo, cfg.seed), cfg.steps, warmup)


def cpu_model() -> str:
    """The processor's model name (from /proc/cpuinfo where there is one)."""
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="Hopper-v5")
    parser.add_argument("--methods", nargs="+", default=["rank-pal-auto", "rank-ral-auto", "dacfo", "gaifo", "bco"])
    parser.add_argument("--steps", type=int, default=12_000)
    parser.add_argument("--warmup", type=int, default=2_048)
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        base = TrainConfig(env=args.env, steps=args.steps, eval_every=args.eval_every, out=Path(tmp))
        reference = {"sac": time_sac(base, args.warmup), "ppo": time_ppo(base, args.warmup)}
        for method in args.methods:
            player = METHODS[method].policy if method in METHODS else "sac"
            player = "sac" if player == "opolo" else player
            cfg = TrainConfig(env=args.env, method=method, steps=args.steps, eval_every=args.eval_every, out=Path(tmp))
            if method == "bco":  # time the rounds after the pre-demonstration phase
                cfg = dataclasses.replace(cfg, cloning=CloningConfig(pre_steps=args.warmup))
            if method == "opolo":  # time TD3's updates, not its random warm-up
                cfg = dataclasses.replace(cfg, td3=TD3Config(start_steps=args.warmup, update_after=args.warmup))
            if (own := OWN_TRAINER_METHODS.get(method)) is not None and own.sac_preset is not None:
                cfg = dataclasses.replace(cfg, sac=sac_preset(own.sac_preset))
            rate = time_game(cfg, args.warmup)
            results.append(
                {
                    "method": method,
                    "steps_per_s": round(rate, 1),
                    "reference": player,
                    "ratio_to_reference": round(rate / reference[player], 3),
                }
            )
    summary = {
        "env": args.env,
        "timed_steps": args.steps - args.warmup,
        "cpu": cpu_model(),
        "sac_steps_per_s": round(reference["sac"], 1),
        "ppo_steps_per_s": round(reference["ppo"], 1),
        "methods": results,
    }
    if args.json:
        print(json.dumps(summary))
        return
    print(
        f"{args.env}, {summary['timed_steps']} timed steps: SAC {summary['sac_steps_per_s']} steps/s, "
        f"PPO {summary['ppo_steps_per_s']} steps/s"
    )
    for row in results:
        print(
            f"{row['method']:>16}: {row['steps_per_s']:>7} steps/s, "
            f"{row['ratio_to_reference']:.3f} x {row['reference']}"
        )


if __name__ == "__main__":
    main()
