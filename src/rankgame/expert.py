"""Train an expert with SAC on the true reward and record its trajectories (``rankgame expert``).

Writes into the output folder:
``policy.msgpack`` (last policy), ``best_policy.msgpack`` (best evaluation so far),
``trajectories.npz`` (episodes of the best policy, see :mod:`rankgame.data.trajectories`),
``metrics.csv`` and ``tb/`` (TensorBoard), ``checkpoint.npz`` (everything ``--resume`` needs).
"""

from __future__ import annotations

import importlib.metadata
import platform
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import jax
import numpy as np
from tqdm import tqdm

from rankgame.checkpoint import (
    CHECKPOINT_NAME,
    checkpoint_to_resume,
    load_run_checkpoint,
    make_out_dir,
    save_checkpoint,
)
from rankgame.cli_args import config_to_json
from rankgame.data.trajectories import Trajectory, save_trajectories
from rankgame.envs.make import make_env
from rankgame.envs.rollout import (
    EVAL_SEED_OFFSET,
    PolicyFn,
    episode_returns,
    episode_succeeded,
    evaluate_episodes,
    random_policy,
    rollout,
    run_episodes,
    success_postfix,
)
from rankgame.errors import RankGameError
from rankgame.logging import RunLogger
from rankgame.policy.io import load_policy, save_policy
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import SACConfig

#: Recorded and random-policy episodes are seeded apart from training and evaluation resets.
RECORD_SEED_OFFSET = 20_000
RANDOM_SEED_OFFSET = 30_000


@dataclass(frozen=True)
class ExpertConfig:
    """Options of ``rankgame expert``."""

    env: str = "Hopper-v5"
    """Gymnasium id of the task."""
    steps: int = 1_000_000
    """Environment steps of SAC training."""
    seed: int = 0
    """Seed of everything random in the run."""
    out: Path = Path("runs/expert")
    """Output folder (created if needed)."""
    eval_every: int = 10_000
    """Environment steps between evaluations of the deterministic policy."""
    eval_episodes: int = 5
    """Episodes per evaluation."""
    trajectories: int = 10
    """Expert episodes to record at the end, from the best evaluated policy."""
    random_episodes: int = 100
    """Episodes of a uniformly random policy, to record the random return used for normalized scores."""
    checkpoint_every: int = 50_000
    """Environment steps between checkpoints (rounded up to evaluations)."""
    resume: bool = False
    """Continue the run in OUT from its last checkpoint, or from step 0 if it stopped before its first one
    (--steps may be raised to train longer)."""
    tensorboard: bool = True
    """Also write TensorBoard event files to OUT/tb."""
    progress: bool = True
    """Show a progress bar."""
    sac: SACConfig = field(default_factory=SACConfig)

    def validate(self) -> None:
        """Raise :class:`RankGameError` for values that make no sense."""
        if self.seed < 0:
            raise RankGameError(f"--seed must be >= 0 (got {self.seed})")
        if min(self.steps, self.eval_every, self.eval_episodes, self.checkpoint_every) <= 0:
            raise RankGameError("--steps, --eval-every, --eval-episodes and --checkpoint-every must be positive")
        if self.trajectories <= 0 or self.random_episodes <= 0:
            raise RankGameError("--trajectories and --random-episodes must be positive")
        try:
            self.sac.validate()
        except ValueError as exc:
            raise RankGameError(f"bad SAC setting: {exc}") from None


def library_versions() -> dict[str, str]:
    """Versions of the libraries that decide the numbers (recorded in data files)."""
    names = ("rankgame", "gymnasium", "mujoco", "jax", "jaxlib", "flax", "optax", "numpy")
    versions = {"python": platform.python_version()}
    for name in names:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = "unknown"
    return versions


def random_return(env_id: str, episodes: int, seed: int) -> tuple[float, float]:
    """Mean and std of the return of uniformly random actions over ``episodes`` episodes."""
    env = make_env(env_id)
    returns = episode_returns(env, random_policy(env, seed), episodes, seed)
    env.close()
    return float(returns.mean()), float(returns.std())


#: ``rankgame record --successful-only`` gives up after this many tries per episode asked for.
MAX_TRIES_PER_EPISODE = 20


def successful_episodes(env: gym.Env, policy: PolicyFn, episodes: int, seed: int) -> tuple[list[Trajectory], int]:
    """The first ``episodes`` episodes that succeed (:func:`~rankgame.envs.rollout.episode_succeeded`)
    among episodes reset with ``seed``, ``seed + 1``, ..., and the number of episodes tried.

    Raises:
        RankGameError: if the task reports no success, or too few episodes succeed within
            ``MAX_TRIES_PER_EPISODE * episodes`` tries.
    """
    kept: list[Trajectory] = []
    tries = 0
    while len(kept) < episodes:
        if tries == MAX_TRIES_PER_EPISODE * episodes:
            raise RankGameError(f"only {len(kept)} of {tries} episodes succeeded; fewer --episodes, or a better policy")
        (episode,), (success_steps,) = run_episodes(env, policy, 1, seed + tries)
        if success_steps is None:
            raise RankGameError("--successful-only: this task reports no success")
        if episode_succeeded(success_steps):
            kept.append(episode)
        tries += 1
    return kept, tries


def record_expert(
    policy_path: Path,
    out: Path,
    episodes: int,
    seed: int,
    random_episodes: int,
    successful_only: bool = False,
    **metadata: Any,
) -> dict[str, Any]:
    """Roll out a saved policy deterministically and write its trajectories with their provenance
    (with ``successful_only``, only episodes that succeed: :func:`successful_episodes`)."""
    saved = load_policy(policy_path)
    env = make_env(saved.env_id)
    if successful_only:
        trajectories, tried = successful_episodes(env, saved.policy_fn(), episodes, seed)
    else:
        trajectories, tried = rollout(env, saved.policy_fn(), episodes, seed), episodes
    env.close()
    rand_mean, rand_std = random_return(saved.env_id, random_episodes, seed + RANDOM_SEED_OFFSET)
    save_trajectories(
        out,
        saved.env_id,
        trajectories,
        **metadata,
        source="expert",
        policy_metadata=saved.metadata,
        record_seed=seed,
        successful_only=successful_only,
        episodes_tried=tried,
        random_return_mean=rand_mean,
        random_return_std=rand_std,
        random_episodes=random_episodes,
        versions=library_versions(),
    )
    returns = [t.ret for t in trajectories]
    return {
        "return_mean": float(np.mean(returns)),
        "return_std": float(np.std(returns)),
        "random_return": rand_mean,
        "episodes_tried": tried,
    }


LOG_COLUMNS = (
    "env_steps",
    "wall_s",
    "steps_per_s",
    "train_return",
    "eval_return",
    "eval_return_std",
    "eval_success",
    "losses/critic",
    "losses/actor",
    "losses/alpha",
    "losses/entropy",
    "losses/q",
)


@dataclass
class _Progress:
    """What the expert run carries from one evaluation to the next (saved in checkpoints)."""

    best_return: float = -np.inf
    best_step: int = 0
    train_return: float = float("nan")
    wall_s: float = 0.0
    eval_s: float = 0.0


def _restore(cfg: ExpertConfig, learner: SACLearner, path: Path) -> _Progress:
    metadata, arrays = load_run_checkpoint(path, config_to_json(cfg), config_to_json(ExpertConfig()), cfg.steps)
    learner.restore(metadata, arrays, seed=cfg.seed + int(metadata["env_steps"]))
    progress = _Progress(**metadata["progress"])
    # The best policy is saved as soon as it is evaluated, possibly after the last checkpoint.
    best_path = path.parent / "best_policy.msgpack"
    if best_path.exists():
        best = load_policy(best_path).metadata
        if best["eval_return"] > progress.best_return:
            progress.best_return, progress.best_step = float(best["eval_return"]), int(best["env_steps"])
    return progress


def train_expert(cfg: ExpertConfig, command: str | None = None) -> dict[str, Any]:
    """Train SAC on the environment reward, keep the best evaluated policy and record its episodes."""
    cfg.validate()
    out = Path(cfg.out)
    resume_from = checkpoint_to_resume(out, cfg.resume)
    env = make_env(cfg.env)  # an unknown or unavailable task fails before OUT is created
    eval_env = make_env(cfg.env)
    make_out_dir(out)
    learner = SACLearner(env, cfg.sac, cfg.seed)
    progress = _restore(cfg, learner, resume_from) if resume_from is not None else _Progress()
    ckpt = out / CHECKPOINT_NAME
    start_step = learner.env_steps
    spec = learner.spec
    logger = RunLogger(out, LOG_COLUMNS, tensorboard=cfg.tensorboard, resume_step=start_step if cfg.resume else None)
    command = command or shlex.join(sys.argv)
    provenance = {"command": command, "seed": cfg.seed, "config": config_to_json(cfg)}
    metrics: dict[str, float] = {}
    start = time.perf_counter() - progress.wall_s
    bar = tqdm(
        total=cfg.steps, initial=start_step, disable=not cfg.progress, unit="step", dynamic_ncols=True, desc=cfg.env
    )
    try:
        for step in range(start_step + 1, cfg.steps + 1):
            result = learner.env_step()
            if result.episode_return is not None:
                progress.train_return = result.episode_return
            metrics = learner.maybe_update() or metrics
            bar.update(1)
            if step % cfg.eval_every == 0 or step == cfg.steps:
                eval_start = time.perf_counter()
                returns, success = evaluate_episodes(
                    eval_env, learner.policy(), cfg.eval_episodes, cfg.seed + EVAL_SEED_OFFSET
                )
                progress.eval_s += time.perf_counter() - eval_start
                progress.wall_s = time.perf_counter() - start
                logger.log(
                    {
                        "env_steps": step,
                        "wall_s": progress.wall_s,
                        "steps_per_s": step / max(progress.wall_s - progress.eval_s, 1e-9),
                        "train_return": progress.train_return,
                        "eval_return": float(returns.mean()),
                        "eval_return_std": float(returns.std()),
                        **({} if success is None else {"eval_success": success}),
                        **metrics,
                    }
                )
                params = jax.device_get(learner.state.actor_params)
                policy_meta = {**provenance, "env_steps": step, "eval_return": float(returns.mean())}
                save_policy(
                    out / "policy.msgpack", learner.sac, params, cfg.env, spec.act_low, spec.act_high, **policy_meta
                )
                if returns.mean() > progress.best_return:
                    progress.best_return, progress.best_step = float(returns.mean()), step
                    save_policy(
                        out / "best_policy.msgpack",
                        learner.sac,
                        params,
                        cfg.env,
                        spec.act_low,
                        spec.act_high,
                        **policy_meta,
                    )
                postfix = {"eval": f"{returns.mean():.0f}", "best": f"{progress.best_return:.0f}"}
                bar.set_postfix({**postfix, **success_postfix(success)})
                if step % cfg.checkpoint_every < cfg.eval_every or step == cfg.steps:
                    learner_meta, arrays = learner.checkpoint()
                    metadata = {**learner_meta, "config": config_to_json(cfg), "progress": vars(progress)}
                    save_checkpoint(ckpt, metadata, arrays)
    finally:
        bar.close()
        logger.close()
    summary = record_expert(
        out / "best_policy.msgpack",
        out / "trajectories.npz",
        cfg.trajectories,
        cfg.seed + RECORD_SEED_OFFSET,
        cfg.random_episodes,
        command=command,
        train_seed=cfg.seed,
        train_steps=cfg.steps,
        best_step=progress.best_step,
    )
    return {"env": cfg.env, "best_eval_return": progress.best_return, "best_step": progress.best_step, **summary}
