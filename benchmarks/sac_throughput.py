"""Env-steps per second of rankgame's JAX SAC and Stable-Baselines3's SAC, measured in one run.

Both train on the same task with the same hyperparameters (network 256x256, batch, learning rate,
learned temperature, 1 gradient step per environment step, gradients applied in chunks of
``update_every`` steps) after the same number of random warm-up steps. The timing covers acting,
stepping the environment and the gradient updates, and starts after a warm-up (compilation for
JAX) that is excluded for both.

    pip install -e ".[bench]"   # stable-baselines3 and torch==2.13.0 (CPU build)
    python benchmarks/sac_throughput.py --env Hopper-v5 --steps 5000 --json
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import jax

from rankgame.envs.make import make_env
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import sac_preset


def time_rankgame(env_id: str, warmup: int, steps: int, batch_size: int, update_every: int, seed: int) -> float:
    """Env-steps/s of rankgame's SAC over ``steps`` steps after ``warmup`` steps."""
    cfg = sac_preset(
        "modern", batch_size=batch_size, start_steps=warmup, update_after=warmup, update_every=update_every
    )
    learner = SACLearner(make_env(env_id), cfg, seed=seed)
    for _ in range(warmup + update_every):  # includes the first update call, which compiles
        learner.env_step()
        learner.maybe_update()
    start = time.perf_counter()
    for _ in range(steps):
        learner.env_step()
        learner.maybe_update()
    jax.block_until_ready(learner.state)
    return steps / (time.perf_counter() - start)


def time_sb3(env_id: str, warmup: int, steps: int, batch_size: int, update_every: int, seed: int) -> float:
    """Env-steps/s of Stable-Baselines3's SAC with the same settings."""
    import gymnasium as gym
    from stable_baselines3 import SAC
    from stable_baselines3.common.callbacks import BaseCallback

    class StepClock(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.start: float | None = None
            self.end: float | None = None

        def _on_step(self) -> bool:
            if self.num_timesteps == warmup + update_every:
                self.start = time.perf_counter()
            if self.num_timesteps == warmup + update_every + steps:
                self.end = time.perf_counter()
            return True

    model = SAC(
        "MlpPolicy",
        gym.make(env_id),
        learning_rate=3e-4,
        buffer_size=1_000_000,
        learning_starts=warmup,
        batch_size=batch_size,
        tau=0.005,
        gamma=0.99,
        train_freq=update_every,
        gradient_steps=update_every,
        ent_coef="auto",
        policy_kwargs={"net_arch": [256, 256]},
        seed=seed,
        device="cpu",
        verbose=0,
    )
    clock = StepClock()
    model.learn(total_timesteps=warmup + update_every + steps + 1, callback=clock)
    assert clock.start is not None and clock.end is not None
    return steps / (clock.end - clock.start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="Hopper-v5")
    parser.add_argument("--warmup", type=int, default=1000, help="random steps before learning (not timed)")
    parser.add_argument("--steps", type=int, default=5000, help="timed steps per library")
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--update-every", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--skip-sb3", action="store_true", help="time rankgame only")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    common = (args.env, args.warmup, args.steps, args.batch_size, args.update_every, args.seed)
    ours = time_rankgame(*common)
    result = {
        "env": args.env,
        "timed_steps": args.steps,
        "batch_size": args.batch_size,
        "update_every": args.update_every,
        "rankgame_steps_per_s": round(ours, 1),
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
    }
    if not args.skip_sb3:
        theirs = time_sb3(*common)
        result["sb3_steps_per_s"] = round(theirs, 1)
        result["ratio"] = round(ours / theirs, 2)
    if args.json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:>22}: {value}")


if __name__ == "__main__":
    main()
