"""Train an expert with SAC on the true reward and record its trajectories (``rankgame expert``).

Writes into the output folder:
``policy.msgpack`` (last policy), ``best_policy.msgpack`` (best evaluation so far),
``trajectories.npz`` (episodes of the best policy, see :mod:`rankgame.data.trajectories`),
``metrics.csv`` and ``tb/`` (TensorBoard), ``checkpoint.npz`` (everything ``--resume`` needs).
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import platform
import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import jax
import numpy as np

from rankgame.config import config_to_json
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
from rankgame.errors import RankGameError, invalid_choices
from rankgame.policy.io import load_policy, save_policy
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import SACConfig
from rankgame.run import RunSettings, open_run, run

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
    """Continue the run in OUT from its last checkpoint, with the settings saved there (--steps may be
    raised to train longer)."""
    tensorboard: bool = True
    """Also write TensorBoard event files to OUT/tb."""
    progress: bool = True
    """Show a progress bar."""
    sac: SACConfig = field(default_factory=SACConfig)

    def validate(self) -> None:
        """Raise :class:`RankGameError` for values that make no sense."""
        if self.seed < 0:
            raise RankGameError(f"--seed must be >= 0 (got {self.seed})")
        if invalid := invalid_choices(self):
            raise RankGameError(f"bad setting: {invalid[0]}")
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


class ExpertTrainer:
    """SAC on the environment reward, keeping the best evaluated policy: the :class:`~rankgame.run.Trainer`
    of ``rankgame expert``."""

    def __init__(self, cfg: ExpertConfig, command: str) -> None:
        self.cfg = cfg
        self.command = command
        self.learner = SACLearner(make_env(cfg.env), cfg.sac, cfg.seed)
        self.eval_env = make_env(cfg.env)
        self.metrics: dict[str, float] = {}
        self.train_return = float("nan")
        self.best_return = -np.inf
        self.best_step = 0

    @property
    def env_steps(self) -> int:
        return self.learner.env_steps

    def step(self, step: int) -> None:
        result = self.learner.env_step()
        if result.episode_return is not None:
            self.train_return = result.episode_return
        self.metrics = self.learner.maybe_update() or self.metrics

    def can_checkpoint(self, step: int) -> bool:
        return step % self.cfg.eval_every == 0

    def evaluate(self) -> dict[str, float]:
        returns, success = evaluate_episodes(
            self.eval_env, self.learner.policy(), self.cfg.eval_episodes, self.cfg.seed + EVAL_SEED_OFFSET
        )
        row = {
            "train_return": self.train_return,
            "eval_return": float(returns.mean()),
            "eval_return_std": float(returns.std()),
        }
        return row if success is None else {**row, "eval_success": success}

    def training_metrics(self) -> dict[str, float]:
        return self.metrics

    def save_policies(self, out: Path, step: int, row: dict[str, float]) -> None:
        """``policy.msgpack`` (this evaluation's actor) and, when it is the best so far, ``best_policy.msgpack``."""
        spec, ret = self.learner.spec, row["eval_return"]
        params = jax.device_get(self.learner.state.actor_params)
        provenance = {"command": self.command, "seed": self.cfg.seed, "config": config_to_json(self.cfg)}
        names = ["policy.msgpack"] + (["best_policy.msgpack"] if ret > self.best_return else [])
        for name in names:
            save_policy(
                out / name,
                self.learner.sac,
                params,
                self.cfg.env,
                spec.act_low,
                spec.act_high,
                **provenance,
                env_steps=step,
                eval_return=ret,
            )
        if ret > self.best_return:
            self.best_return, self.best_step = ret, step

    def postfix(self, row: dict[str, float]) -> dict[str, str]:
        fields = {"eval": f"{row['eval_return']:.0f}", "best": f"{self.best_return:.0f}"}
        return {**fields, **success_postfix(row.get("eval_success"))}

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        metadata, arrays = self.learner.checkpoint()
        progress = {"best_return": self.best_return, "best_step": self.best_step, "train_return": self.train_return}
        return {**metadata, "progress": progress}, arrays

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        self.learner.restore(metadata, arrays, seed=self.cfg.seed + int(metadata["env_steps"]))
        progress = metadata["progress"]
        self.best_return, self.best_step = float(progress["best_return"]), int(progress["best_step"])
        self.train_return = float(progress["train_return"])


def train_expert(cfg: ExpertConfig, command: str | None = None) -> dict[str, Any]:
    """Train SAC on the environment reward, keep the best evaluated policy and record its episodes."""
    cfg = dataclasses.replace(cfg, out=Path(cfg.out))
    cfg.validate()
    settings = RunSettings(
        cfg.out, cfg.steps, cfg.eval_every, cfg.checkpoint_every, cfg.resume, cfg.tensorboard, cfg.progress, cfg.env
    )
    as_json = config_to_json(cfg)
    resumed = open_run(settings, as_json)
    command = command or shlex.join(sys.argv)
    trainer = ExpertTrainer(cfg, command)  # an unknown or unavailable task fails before OUT is created
    run(trainer, settings, resumed, as_json, LOG_COLUMNS, command)
    best = cfg.out / "best_policy.msgpack"
    if best.exists():  # saved as soon as it is evaluated, possibly after the last checkpoint
        saved = load_policy(best).metadata
        if saved["eval_return"] > trainer.best_return:
            trainer.best_return, trainer.best_step = float(saved["eval_return"]), int(saved["env_steps"])
    summary = record_expert(
        best,
        cfg.out / "trajectories.npz",
        cfg.trajectories,
        cfg.seed + RECORD_SEED_OFFSET,
        cfg.random_episodes,
        command=command,
        train_seed=cfg.seed,
        train_steps=cfg.steps,
        best_step=trainer.best_step,
    )
    return {"env": cfg.env, "best_eval_return": trainer.best_return, "best_step": trainer.best_step, **summary}
