"""The ranking game's training loop (Alg. 1-3): one loop for every method.

Each iteration the policy player collects ``n_pol`` environment steps while SAC takes one gradient
step per environment step on batches relabelled by the current reward (data sharing: the same
transitions feed SAC and the ranking data). The episodes finished in the iteration, padded with
absorbing states to the horizon, become agent data of the ranking dataset; the leader decides what
the reward player keeps and how long it trains.
"""

from __future__ import annotations

import json
import shlex
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import jax
import numpy as np
from tqdm import tqdm

from rankgame.atomic import atomic_write_bytes
from rankgame.checkpoint import (
    CHECKPOINT_NAME,
    checkpoint_to_resume,
    flatten_tree,
    load_run_checkpoint,
    make_out_dir,
    save_checkpoint,
    unflatten_tree,
)
from rankgame.cli_args import config_to_json
from rankgame.data.experts import load_expert_data, normalized_score, shipped_envs
from rankgame.data.preferences import load_preferences, shipped_preferences_path
from rankgame.data.trajectories import Trajectory, TrajectoryFile
from rankgame.envs.make import EnvSpec, env_spec, make_env
from rankgame.envs.rollout import (
    EVAL_SEED_OFFSET,
    episode_returns,
    evaluate_episodes,
    random_policy,
    success_postfix,
    to_normalized_action,
)
from rankgame.errors import RankGameError
from rankgame.game.leaders import add_agent_data, fit_reward
from rankgame.game.methods import METHODS
from rankgame.logging import RunLogger
from rankgame.policy.io import save_policy
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import SACConfig
from rankgame.reward.features import trajectory_features
from rankgame.reward.nets import RewardInput, feature_columns, feature_dim, parse_obs_columns
from rankgame.reward.offline_rankings import OfflineRankings
from rankgame.reward.player import RewardConfig, RewardPlayer
from rankgame.reward.ranking_data import RankingData
from rankgame.reward.targets import Schedule, lambda_grid, target_schedule


@dataclass(frozen=True)
class TrainConfig:
    """Options of ``rankgame train``."""

    env: str = "Hopper-v5"
    """Gymnasium id of the task."""
    method: Literal[
        "rank-pal-auto",
        "rank-ral-auto",
        "rank-pal-vanilla",
        "rank-ral-vanilla",
        "rank-pal-pref",
        "rank-ral-pref",
        "imit-pal",
        "imit-ral",
    ] = "rank-pal-auto"
    """Ranking source x loss x leader (see rankgame.game.methods)."""
    steps: int = 300_000
    """Environment steps of training."""
    seed: int = 0
    """Seed of everything random in the run."""
    out: Path = Path("runs/train")
    """Output folder: metrics.csv, tb/, checkpoint.npz, policy.msgpack (the actor of the last evaluation)."""
    expert: Path | None = None
    """Expert trajectory file (default: the shipped data for ENV)."""
    preferences: Path | None = None
    """Offline trajectories ranked below the expert, for the pref methods (default: the shipped data
    for ENV; make a file with `rankgame preferences`)."""
    pref_noise: float = 0.0
    """Share of the offline rankings' state and snippet labels replaced, once per run, by the rank of
    another offline trajectory (noisy preferences; pref methods)."""
    expert_trajectories: int = 1
    """How many expert trajectories to imitate (the first ones of the file)."""
    setting: Literal["lfo", "lfd"] = "lfo"
    """Learn from observations only (lfo) or from observations and actions (lfd)."""
    reward_input: Literal["default", "s", "ss", "sa"] = "default"
    """Reward inputs: s, (s, s') or (s, a); default: s for lfo, sa for lfd."""
    reward_obs: str = "all"
    """Observation entries the reward reads: all, or indices and half-open ranges such as 0:27 (on
    Ant-v5, the entries before its contact forces, which gym's Ant-v2 reported as zeros)."""
    k: float = 10.0
    """Performance gap k: expert inputs are regressed to agent_target + k."""
    agent_target: float = 0.0
    """Regression target of agent inputs (the paper's 0)."""
    schedule: Schedule = "exp"
    """Targets of the auto mixtures: linear or exp."""
    beta: float = -1.0
    """Temperature of the exp schedule (Table 4: -1; the authors' Ant configuration uses -2)."""
    termination: Literal["absorbing", "done"] = "absorbing"
    """How SAC treats an early-terminated episode: absorbing (DAC-style absorbing state whose value
    follows the learned reward) or done (a terminal mask: ending is worth 0, as in the authors' code)."""
    interpolations: int = 4
    """Interior mixtures between agent and expert (auto rankings): 4 gives lambda = 0, 0.2, ..., 1, the
    grid of the authors' code (Table 4's "5 interpolations" counts its five steps)."""
    mixup: Literal["trajectory", "state"] = "trajectory"
    """How the auto rankings pair agent and expert states: trajectory (time-aligned, the paper's
    method) or state (an expert state from a random time step, the regularizer ablation's baseline)."""
    policy_updates: int | None = None
    """Environment steps (and SAC updates) per game iteration, n_pol; default: the horizon H."""
    switch_at: int | None = None
    """Non-stationary imitation (Sec. 5.3): after this many environment steps, switch to --switch-env
    and/or --switch-expert; default: never."""
    switch_env: str | None = None
    """Task to train and evaluate on after --switch-at, with the same spaces as ENV (e.g.
    rankgame/HopperHeavy-v5: changed dynamics); default: ENV throughout."""
    switch_expert: Path | None = None
    """Expert data to imitate after --switch-at (e.g. an expert of rankgame/HopperBackward-v5: changed
    intent); scores are then normalized by its returns. Default: the shipped data of --switch-env if
    there is any, else the same expert throughout."""
    eval_every: int = 10_000
    """Environment steps between evaluations of the deterministic policy on the true reward."""
    eval_episodes: int = 5
    """Episodes per evaluation."""
    checkpoint_every: int = 20_000
    """Environment steps between checkpoints (rounded to whole iterations); the last step always gets one."""
    resume: bool = False
    """Continue the run in OUT from its last checkpoint, or from step 0 if it stopped before its first one."""
    tensorboard: bool = True
    """Also write TensorBoard event files to OUT/tb."""
    progress: bool = True
    """Show a progress bar."""
    sac: SACConfig = field(default_factory=SACConfig)
    reward: RewardConfig = field(default_factory=RewardConfig)

    @property
    def resolved_reward_input(self) -> RewardInput:
        if self.reward_input != "default":
            return self.reward_input
        return "s" if self.setting == "lfo" else "sa"

    def validate(self) -> None:
        """Raise :class:`RankGameError` with a one-line reason for settings that make no sense."""
        if self.method not in METHODS:
            raise RankGameError(f"unknown method {self.method!r}; choose from {', '.join(METHODS)}")
        positive = {
            "--steps": self.steps,
            "--eval-every": self.eval_every,
            "--eval-episodes": self.eval_episodes,
            "--expert-trajectories": self.expert_trajectories,
            "--checkpoint-every": self.checkpoint_every,
        }
        for name, value in positive.items():
            if value <= 0:
                raise RankGameError(f"{name} must be positive (got {value})")
        if self.seed < 0:
            raise RankGameError(f"--seed must be >= 0 (got {self.seed})")
        if self.policy_updates is not None and self.policy_updates <= 0:
            raise RankGameError("--policy-updates must be positive")
        if self.k <= 0:
            raise RankGameError("--k must be positive")
        if self.interpolations < 0:
            raise RankGameError("--interpolations must be >= 0")
        if self.mixup != "trajectory" and METHODS[self.method].rankings != "auto":
            raise RankGameError(f"--mixup is used only by the auto methods, not {self.method}")
        if self.preferences is not None and METHODS[self.method].rankings != "pref":
            raise RankGameError(f"--preferences is used only by the pref methods, not {self.method}")
        if not 0.0 <= self.pref_noise <= 1.0:
            raise RankGameError(f"--pref-noise must lie in [0, 1] (got {self.pref_noise})")
        if self.pref_noise > 0.0 and METHODS[self.method].rankings != "pref":
            raise RankGameError(f"--pref-noise is used only by the pref methods, not {self.method}")
        switching = self.switch_env is not None or self.switch_expert is not None
        if (self.switch_at is not None) != switching:
            raise RankGameError("--switch-at needs --switch-env or --switch-expert, and they need --switch-at")
        if self.switch_at is not None and not 0 < self.switch_at < self.steps:
            raise RankGameError(f"--switch-at must lie between 0 and --steps {self.steps} (got {self.switch_at})")
        if self.switch_expert is not None and METHODS[self.method].rankings == "pref":
            raise RankGameError("--switch-expert cannot be combined with the pref methods' offline rankings")
        if self.setting == "lfo" and self.resolved_reward_input == "sa":
            raise RankGameError("--reward-input sa needs expert actions: use --setting lfd")
        if not np.isfinite([self.k, self.agent_target, self.beta]).all():
            raise RankGameError("--k, --agent-target and --beta must be finite")
        try:
            self.sac.validate()
            self.reward.validate()
        except ValueError as exc:
            raise RankGameError(f"bad setting: {exc}") from None
        if self.agent_target + self.k > self.reward.r_max or self.agent_target < -self.reward.r_max:
            raise RankGameError(
                f"targets [{self.agent_target}, {self.agent_target + self.k}] exceed the reward bound "
                f"[-{self.reward.r_max}, {self.reward.r_max}] (--reward.r-max)"
            )


def _eval_postfix(evaluation: dict[str, float]) -> dict[str, str]:
    """Progress-bar fields of an evaluation: normalized score, return and, where known, success rate."""
    return {
        "score": f"{evaluation['normalized_score']:.1f}",
        "ret": f"{evaluation['eval_return']:.0f}",
        **success_postfix(evaluation.get("eval_success")),
    }


#: Checkpoint array of the episodes finished in the iteration in progress.
FINISHED_KEY = "game/finished"

#: The actor of the run's last evaluation, in the run folder (``rankgame evaluate --policy``).
POLICY_NAME = "policy.msgpack"

LOG_COLUMNS = (
    "env_steps",
    "wall_s",
    "steps_per_s",
    "eval_return",
    "normalized_score",
    "eval_success",
    "reward/train_loss",
    "reward/holdout_loss",
    "reward/agent",
    "reward/expert",
    "losses/critic",
    "losses/actor",
    "losses/alpha",
    "losses/reward",
)


class _Episode:
    """Observations and normalized actions of the episode being played."""

    def __init__(self) -> None:
        self.obs: list[np.ndarray] = []
        self.acts: list[np.ndarray] = []


def load_expert(cfg: TrainConfig, path: Path | None, env_id: str) -> TrajectoryFile:
    """The expert data to imitate, recorded on ``env_id``: the file at ``path``, or the shipped data of
    ``env_id`` when ``path`` is None. It must hold at least ``--expert-trajectories`` trajectories."""
    data = load_expert_data(path, env_id)
    if len(data.trajectories) < cfg.expert_trajectories:
        raise RankGameError(
            f"{path or f'the shipped expert data of {env_id}'} holds {len(data.trajectories)} trajectories; "
            f"--expert-trajectories asks for {cfg.expert_trajectories}"
        )
    return data


def _require_dims(data: TrajectoryFile, spec: EnvSpec, what: str) -> None:
    """A one-line error if recorded trajectories do not have the environment's dimensions."""
    if (data.obs_dim, data.act_dim) != (spec.obs_dim, spec.act_dim):
        raise RankGameError(
            f"{what} has obs_dim={data.obs_dim}, act_dim={data.act_dim}; {data.env_id} has "
            f"obs_dim={spec.obs_dim}, act_dim={spec.act_dim}"
        )


class RankingGame:
    """All state of one training run, built from a :class:`TrainConfig`."""

    def __init__(self, cfg: TrainConfig) -> None:
        cfg.validate()
        self.cfg = cfg
        self.method = METHODS[cfg.method]
        self.env = make_env(cfg.env)
        self.eval_env = make_env(cfg.env)
        self.env_id = cfg.env
        """The task the policy acts in and is evaluated on (``--switch-env`` after a switch)."""
        expert = load_expert(cfg, cfg.expert, cfg.env)
        spec = env_spec(self.env)
        _require_dims(expert, spec, "expert data")
        self.horizon = spec.max_episode_steps or max(len(t) for t in expert.trajectories)
        self.n_pol = cfg.policy_updates or self.horizon
        if cfg.steps < self.n_pol:
            raise RankGameError(
                f"--steps {cfg.steps} is shorter than one game iteration ({self.n_pol} steps, the horizon or "
                "--policy-updates): the reward would never be fit"
            )
        reward_input = cfg.resolved_reward_input
        try:
            obs_columns = parse_obs_columns(cfg.reward_obs, spec.obs_dim)
        except ValueError as exc:
            raise RankGameError(f"--reward-obs: {exc}") from None
        every_entry = obs_columns == tuple(range(spec.obs_dim))
        columns = None if every_entry else feature_columns(spec.obs_dim, spec.act_dim, reward_input, obs_columns)
        expert_inputs = self._inputs(expert.trajectories[: cfg.expert_trajectories], "expert data")
        offline = self._offline_rankings(expert_inputs) if self.method.rankings == "pref" else None
        self.player = RewardPlayer(
            feature_dim(spec.obs_dim, spec.act_dim, reward_input),
            reward_input,
            self.method.loss,
            cfg.reward,
            columns,
            offline,
        )
        # SAC relabels its batches with the reward player's current reward.
        self.learner = SACLearner(
            self.env,
            cfg.sac,
            cfg.seed,
            reward_fn=self.player.reward_fn,
            store_env_reward=False,
            absorbing=True,
            absorbing_transitions=cfg.termination == "absorbing",
        )
        self.reward_state = self.player.init(jax.random.fold_in(jax.random.key(cfg.seed), 1))
        self.rng = np.random.default_rng([cfg.seed, 1])

        lambdas = lambda_grid(cfg.interpolations) if self.method.rankings == "auto" else np.array([0.0, 1.0])
        targets = target_schedule(lambdas, cfg.agent_target, cfg.agent_target + cfg.k, cfg.schedule, cfg.beta)
        self.data = RankingData(
            expert_inputs,
            lambdas,
            targets,
            cfg.reward.holdout_fraction,
            flag_index=spec.obs_dim,
            time_aligned=cfg.mixup == "trajectory",
            holdout_real_only=cfg.reward.holdout_rows == "real",
        )
        self._set_score_scale(expert)
        self.switch_expert, self._switch_inputs = self._check_switch(spec)
        self.episode = _Episode()
        self.finished: list[np.ndarray] = []
        self.reward_metrics: dict[str, float] = {}
        self.sac_metrics: dict[str, float] = {}

    def _set_score_scale(self, expert: TrajectoryFile) -> None:
        """The expert and random returns that normalize scores, from the expert file's records."""
        self.expert_return = float(expert.returns.mean())
        self.random_return = float(expert.metadata.get("random_return_mean", np.nan))
        if not np.isfinite(self.random_return):  # expert file without it: measure on the evaluation env
            policy = random_policy(self.eval_env, self.cfg.seed)
            self.random_return = float(episode_returns(self.eval_env, policy, 20, self.cfg.seed).mean())
        if self.expert_return == self.random_return:
            print("expert and random returns are equal: the normalized score is not defined", file=sys.stderr)

    def _check_switch(self, spec: EnvSpec) -> tuple[TrajectoryFile | None, np.ndarray | None]:
        """Check the ``--switch-env`` task and ``--switch-expert`` data before training starts; returns the
        switch expert data and its reward inputs ``(M, H, d)``, if there is any."""
        cfg = self.cfg
        if cfg.switch_env is not None:
            env = make_env(cfg.switch_env)
            new = env_spec(env)
            env.close()
            shapes = [(s.obs_dim, s.act_dim, s.max_episode_steps) for s in (new, spec)]
            if shapes[0] != shapes[1]:
                raise RankGameError(
                    f"--switch-env {cfg.switch_env} has (obs_dim, act_dim, horizon) = {shapes[0]}; "
                    f"{cfg.env} has {shapes[1]}"
                )
        if cfg.switch_expert is None and cfg.switch_env not in shipped_envs():
            return None, None
        expert = load_expert(cfg, cfg.switch_expert, cfg.switch_env or cfg.env)
        _require_dims(expert, spec, "--switch-expert data")
        return expert, self._inputs(expert.trajectories[: cfg.expert_trajectories], "--switch-expert data")

    def switch(self) -> None:
        """The non-stationary change at ``--switch-at`` (Sec. 5.3): the policy acts in and is evaluated on
        ``--switch-env``, and the agent is ranked below ``--switch-expert``. The replay buffer, the
        ranking data gathered so far and both players' parameters carry over; the episode in progress
        is abandoned."""
        cfg = self.cfg
        assert cfg.switch_at is not None
        if cfg.switch_env is not None:
            self.eval_env.close()
            self.eval_env = make_env(cfg.switch_env)
            self.env_id = cfg.switch_env
            self.learner.switch_env(make_env(cfg.switch_env), seed=cfg.seed + cfg.switch_at)
            self.env = self.learner.env
            self.episode = _Episode()
        if self.switch_expert is not None and self._switch_inputs is not None:
            self.data.replace_expert(self._switch_inputs, self.rng)
            self._set_score_scale(self.switch_expert)

    def _features(self, obs: np.ndarray, acts_norm: np.ndarray, terminated: bool) -> np.ndarray:
        return trajectory_features(obs, acts_norm, terminated, self.horizon, self.cfg.resolved_reward_input)

    def _inputs(self, trajectories: Sequence[Trajectory], what: str) -> np.ndarray:
        """Reward inputs ``(n, H, d)`` of recorded trajectories, padded to the horizon."""
        spec = env_spec(self.env)
        try:
            return np.stack(
                [
                    self._features(t.obs, to_normalized_action(t.acts, spec.act_low, spec.act_high), t.terminated[-1])
                    for t in trajectories
                ]
            )
        except ValueError as exc:
            raise RankGameError(f"{what} cannot be used on {self.cfg.env}: {exc}") from None

    def _offline_rankings(self, expert_inputs: np.ndarray) -> OfflineRankings:
        """The (pref) chain: the preference file's trajectories, worst first, below the expert.

        Trajectory ``i`` of ``p`` gets the schedule's target at ``i / p`` of the way from the agent's
        target to the expert's (App. B.1 with offline trajectories in place of mixtures).
        """
        cfg = self.cfg
        path = cfg.preferences if cfg.preferences is not None else shipped_preferences_path(cfg.env)
        data, order = load_preferences(path, cfg.env)
        _require_dims(data, env_spec(self.env), "preference data")
        ranked = self._inputs([data.trajectories[i] for i in order], "preference data")
        positions = np.arange(len(ranked) + 1) / len(ranked)
        targets = target_schedule(positions, cfg.agent_target, cfg.agent_target + cfg.k, cfg.schedule, cfg.beta)
        try:  # the label noise gets its own stream (SAC draws from `seed`, the ranking data from [seed, 1])
            return OfflineRankings(
                ranked, expert_inputs, targets, cfg.reward.snippet_length, cfg.pref_noise, noise_seed=[cfg.seed, 2]
            )
        except ValueError as exc:
            raise RankGameError(f"bad preference setting: {exc}") from None

    def env_step(self) -> None:
        """One environment step and the SAC updates due after it."""
        learner = self.learner
        result = learner.env_step()
        if not self.episode.obs:
            self.episode.obs.append(result.obs)
        self.episode.obs.append(result.next_obs)
        self.episode.acts.append(result.act_norm)
        if result.terminated or result.truncated:
            if result.terminated or len(self.episode.acts) >= self.horizon:
                obs, acts = np.asarray(self.episode.obs), np.asarray(self.episode.acts, np.float32)
                self.finished.append(self._features(obs, acts, result.terminated))
            self.episode = _Episode()
        self.sac_metrics = learner.maybe_update(self.reward_state.params) or self.sac_metrics

    def reward_turn(self) -> None:
        """The reward player's move at the end of an iteration (nothing if no episode finished)."""
        if not self.finished:
            return
        new = np.concatenate(self.finished)
        add_agent_data(self.method.leader, self.data, self.finished, self.rng)
        self.finished = []
        self.reward_state, self.reward_metrics = fit_reward(
            self.method.leader, self.player, self.reward_state, self.data, self.rng
        )
        self.reward_metrics["reward/agent"] = self._mean_real_reward(new)
        self.reward_metrics["reward/expert"] = self._mean_real_reward(self.data.expert.reshape(-1, self.data.dim))

    def _mean_real_reward(self, inputs: np.ndarray) -> float:
        """Mean learned reward ``()`` over the inputs ``(N, d)`` that are real states, not absorbing ones."""
        real = inputs[inputs[:, self.learner.spec.obs_dim] == 0.0]
        return self.player.mean_reward(self.reward_state.params, real) if len(real) else float("nan")

    def evaluate(self) -> dict[str, float]:
        """The deterministic policy's mean true return, its normalized score and, for tasks that report
        success, its success rate (``eval_return``, ``normalized_score``, ``eval_success``)."""
        returns, success = evaluate_episodes(
            self.eval_env, self.learner.policy(), self.cfg.eval_episodes, self.cfg.seed + EVAL_SEED_OFFSET
        )
        mean = float(returns.mean())
        result = {
            "eval_return": mean,
            "normalized_score": float(normalized_score(mean, self.expert_return, self.random_return)),
        }
        return result if success is None else {**result, "eval_success": success}

    # --- checkpoints -------------------------------------------------------------------------
    def save(self, path: Path, extra: dict[str, Any]) -> None:
        learner_meta, learner_arrays = self.learner.checkpoint()
        metadata = {
            **extra,
            **learner_meta,
            "config": config_to_json(self.cfg),
            "game_rng": self.rng.bit_generator.state,
            "reward_metrics": self.reward_metrics,
        }
        arrays = {
            **learner_arrays,
            **flatten_tree("reward", self.reward_state),
            **self.data.state_dict(),
            FINISHED_KEY: self._finished_array(),
        }
        save_checkpoint(path, metadata, arrays)

    def save_policy(self, path: Path, **metadata: Any) -> None:
        """Write the current actor for ``rankgame evaluate``, atomically (:func:`save_policy`), marked as
        one that reads the absorbing flag the game appends to observations."""
        spec = self.learner.spec
        params = jax.device_get(self.learner.state.actor_params)
        save_policy(
            path, self.learner.sac, params, self.env_id, spec.act_low, spec.act_high, absorbing_flag=True, **metadata
        )

    def _finished_array(self) -> np.ndarray:
        """This iteration's finished episodes, not yet ranked, as reward inputs ``(n, H, d)``."""
        if self.finished:
            return np.stack(self.finished)
        return np.zeros((0, self.horizon, self.data.dim), np.float32)

    def restore(self, path: Path) -> dict[str, Any]:
        metadata, arrays = load_run_checkpoint(
            path, config_to_json(self.cfg), config_to_json(TrainConfig()), self.cfg.steps
        )
        if self.cfg.switch_at is not None and int(metadata["env_steps"]) > self.cfg.switch_at:
            self.switch()
        self.learner.restore(metadata, arrays, seed=self.cfg.seed + int(metadata["env_steps"]))
        self.reward_state = unflatten_tree("reward", arrays, self.reward_state)
        self.data.load_state_dict(arrays)
        # A checkpoint inside an iteration (a run's last step) holds the episodes it had finished;
        # one at an iteration's end (and every checkpoint of earlier versions) has none.
        self.finished = list(arrays.get(FINISHED_KEY, ()))
        self.rng.bit_generator.state = metadata["game_rng"]
        self.reward_metrics = metadata["reward_metrics"]
        return metadata


def train(cfg: TrainConfig, command: str | None = None) -> dict[str, Any]:
    """Run (or resume) the ranking game and return a summary of the final evaluation."""
    cfg.validate()
    out = Path(cfg.out)
    ckpt = checkpoint_to_resume(out, cfg.resume)
    game = RankingGame(cfg)  # bad tasks or data fail before OUT is created
    make_out_dir(out)
    elapsed, eval_s = 0.0, 0.0  # wall-clock seconds of the whole run and of its evaluations
    if ckpt is not None:
        saved = game.restore(ckpt)
        elapsed, eval_s = float(saved["wall_s"]), float(saved.get("eval_s", 0.0))
    command = command or shlex.join(sys.argv)
    atomic_write_bytes(out / "config.json", json.dumps({"command": command, **config_to_json(cfg)}, indent=2).encode())
    logger = RunLogger(
        out, LOG_COLUMNS, tensorboard=cfg.tensorboard, resume_step=game.learner.env_steps if cfg.resume else None
    )
    start_step = game.learner.env_steps
    start = time.perf_counter() - elapsed
    last_eval: dict[str, float] = {"eval_return": float("nan"), "normalized_score": float("nan")}
    bar = tqdm(
        total=cfg.steps,
        initial=start_step,
        disable=not cfg.progress,
        unit="step",
        dynamic_ncols=True,
        desc=f"{cfg.method} {cfg.env}",
    )
    try:
        for step in range(start_step + 1, cfg.steps + 1):
            if cfg.switch_at is not None and step == cfg.switch_at + 1:  # evaluations at <= switch_at: before
                game.switch()
            game.env_step()
            at_iteration_end = step % game.n_pol == 0
            if at_iteration_end:
                game.reward_turn()
            if step % cfg.eval_every == 0 or step == cfg.steps:
                eval_start = time.perf_counter()
                last_eval = game.evaluate()
                eval_s += time.perf_counter() - eval_start
                game.save_policy(
                    out / POLICY_NAME, command=command, env_steps=step, eval_return=last_eval["eval_return"]
                )
                wall = time.perf_counter() - start
                logger.log(
                    {
                        "env_steps": step,
                        "wall_s": wall,
                        "steps_per_s": step / max(wall - eval_s, 1e-9),  # training only, as in `rankgame expert`
                        **last_eval,
                        **game.reward_metrics,
                        **game.sac_metrics,
                    }
                )
                bar.set_postfix(_eval_postfix(last_eval))
            if (at_iteration_end and step % cfg.checkpoint_every < game.n_pol) or step == cfg.steps:
                game.save(out / CHECKPOINT_NAME, {"wall_s": time.perf_counter() - start, "eval_s": eval_s})
            bar.update(1)
    finally:
        bar.close()
        logger.close()
    return {
        "env": game.env_id,
        "method": cfg.method,
        "steps": cfg.steps,
        **last_eval,
    }
