"""The ranking game (Alg. 1): one loop for every method of :data:`~rankgame.game.methods.METHODS`.

Each iteration the policy player collects ``n_pol`` environment steps while SAC takes its gradient
steps on batches relabelled by the current reward (data sharing: the same transitions feed SAC and
the rankings). The episodes finished in the iteration, padded with absorbing states to the horizon,
become agent data of the rankings; the leader decides what the reward player keeps and how long it
trains. :class:`RankingGame` is the :class:`~rankgame.run.Trainer` that :func:`rankgame.training.train`
hands to the run harness.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jax
import numpy as np

from rankgame.checkpoint import flatten_tree, unflatten_tree
from rankgame.config import TrainConfig
from rankgame.data.trajectories import Trajectory, TrajectoryFile
from rankgame.envs.make import env_spec, make_env
from rankgame.envs.rollout import EVAL_SEED_OFFSET, run_episodes, to_normalized_action
from rankgame.errors import NonFiniteError, RankGameError
from rankgame.game.data import Preferences
from rankgame.game.leaders import make_leader
from rankgame.game.methods import METHODS
from rankgame.game.rankings import build_rankings
from rankgame.game.selection import SELECTED_POLICY_NAME, SELECTION_COLUMN, PolicySelection, learned_return_ratio
from rankgame.game.switch import TaskSwitch
from rankgame.policy.players import iteration_steps, make_policy_player
from rankgame.reward.averaging import RewardAverage
from rankgame.reward.inputs import InputLayout, parse_obs_columns
from rankgame.reward.losses import LOSSES
from rankgame.reward.player import RewardPlayer
from rankgame.run import POLICY_NAME
from rankgame.scores import EVAL_COLUMNS, ScoreScale, score_postfix

#: Checkpoint array of the episodes finished in the iteration in progress.
FINISHED_KEY = "game/finished"

LOG_COLUMNS = (
    *EVAL_COLUMNS,
    SELECTION_COLUMN,
    "reward/train_loss",
    "reward/holdout_loss",
    "reward/agent",
    "reward/expert",
    "losses/critic",
    "losses/actor",
    "losses/alpha",
    "losses/reward",
)


class RankingGame:
    """All state of one training run.

    Args:
        cfg: the run's settings (validated by the caller).
        expert: the expert data to imitate, recorded on ``cfg.env``.
        preferences: the offline rankings of the pref methods, else None.
        switch: the non-stationary change, else None.
    """

    def __init__(
        self,
        cfg: TrainConfig,
        expert: TrajectoryFile,
        preferences: Preferences | None = None,
        switch: TaskSwitch | None = None,
    ) -> None:
        self.cfg = cfg
        self.method = METHODS[cfg.method]
        self.env = make_env(cfg.env)
        self.eval_env = make_env(cfg.env)
        self.env_id = cfg.env
        """The task the policy acts in and is evaluated on (``--switch.env`` after a switch)."""
        self.command = ""
        """The command line recorded in saved policies."""
        spec = self.spec = env_spec(self.env)
        self.horizon = spec.max_episode_steps or max(len(t) for t in expert.trajectories)
        own_length = None if self.method.iteration_horizons is None else self.method.iteration_horizons * self.horizon
        self.n_pol = cfg.policy_updates or own_length or iteration_steps(self.method.policy, cfg, self.horizon)
        if cfg.steps < self.n_pol:
            raise RankGameError(
                f"--steps {cfg.steps} is shorter than one game iteration ({self.n_pol} steps, the horizon or "
                "--policy-updates): the reward would never be fit"
            )
        self.layout = InputLayout(spec.obs_dim, spec.act_dim, cfg.resolved_reward_input)
        try:
            columns = self.layout.columns(parse_obs_columns(cfg.reward_obs, spec.obs_dim))
        except ValueError as exc:
            raise RankGameError(f"--reward-obs: {exc}") from None
        loss = LOSSES[self.method.loss]
        expert_inputs = self._inputs(expert.trajectories[: cfg.expert_trajectories], "expert data")
        ranked = None if preferences is None else self._inputs(preferences.ranked, "preference data")
        try:  # the preference noise gets its own stream (SAC draws from `seed`, the game from [seed, 1])
            self.rankings = build_rankings(
                self.method.rankings,
                cfg.rankings,
                expert_inputs,
                self.layout,
                cfg.leader.holdout_fraction,
                loss,
                ranked,
                cfg.ablation.mixup,
                noise_seed=[cfg.seed, 2],
                ratio_seed=cfg.seed,
                penalty_points=loss.gradient_penalty or cfg.reward.ranking_gradient_penalty > 0.0,
            )
        except ValueError as exc:
            raise RankGameError(f"bad rankings setting: {exc}") from None
        self.leader = make_leader(
            self.method.leader,
            cfg.leader,
            cfg.ablation.leader_budget,
            cfg.ablation.budget_rows,
            self.n_pol,
            self.method.reward_steps,
        )
        self.player = RewardPlayer(
            self.layout, loss, cfg.reward, self.rankings, columns, spectral_norm=cfg.ablation.spectral_norm
        )
        # The policy player relabels its batches with the reward player's current reward (or the mean of
        # its last ones: --reward.policy-window).
        imitated = expert.trajectories[: cfg.expert_trajectories]
        self.averaging = RewardAverage(self.player.reward_fn, cfg.reward.policy_window)
        self.learner = make_policy_player(self.method.policy, self.env, cfg, self.averaging.reward_fn, imitated)
        self.reward_state = self.player.init(jax.random.fold_in(jax.random.key(cfg.seed), 1))
        self.policy_reward = self.averaging.start(self.reward_state.params)
        self.rng = np.random.default_rng([cfg.seed, 1])
        self.scale = ScoreScale.of(expert, self.eval_env, cfg.seed)
        self.switch = switch
        if switch is not None and switch.expert is not None:
            self._switch_inputs = self._inputs(
                switch.expert.trajectories[: cfg.expert_trajectories], "--switch.expert data"
            )
        self._episode_obs: list[np.ndarray] = []
        self._episode_acts: list[np.ndarray] = []
        self.finished: list[np.ndarray] = []
        self.reward_metrics: dict[str, float] = {}
        self.policy_metrics: dict[str, float] = {}
        self.selection = PolicySelection()

    @property
    def env_steps(self) -> int:
        return self.learner.env_steps

    @property
    def log_columns(self) -> tuple[str, ...]:
        """The columns of ``metrics.csv``: :data:`LOG_COLUMNS`, those of the method's loss and policy player,
        and the gradient penalty's value when a ranking loss has one (``--reward.ranking-gradient-penalty``)."""
        penalty = ("reward/gradient_penalty",) if self.cfg.reward.ranking_gradient_penalty > 0.0 else ()
        return (*LOG_COLUMNS, *self.player.loss.log_columns, *penalty, *self.learner.log_columns)

    def _inputs(self, trajectories: list[Trajectory] | tuple[Trajectory, ...], what: str) -> np.ndarray:
        """Reward inputs ``(n, H, d)`` of recorded trajectories, padded to the horizon."""
        spec = self.spec  # the switch task, if any, has the same spaces
        try:
            return np.stack(
                [
                    self.layout.episode(
                        t.obs, to_normalized_action(t.acts, spec.act_low, spec.act_high), t.terminated[-1], self.horizon
                    )
                    for t in trajectories
                ]
            )
        except ValueError as exc:
            raise RankGameError(f"{what} cannot be used on {self.cfg.env}: {exc}") from None

    # --- Algorithm 1 --------------------------------------------------------------------------
    def step(self, step: int) -> None:
        """Environment step ``step``, the policy updates due after it, and the reward's turn at an iteration's end.

        An off-policy player (SAC) updates before the reward's turn, as in Alg. 1. An on-policy player
        (PPO) updates once per iteration on the rollout just collected, so the reward moves first and
        the update reads the rollout relabelled by the reward that has just seen it (GAIL's order).
        """
        if self.switch is not None and self.switch.due(step):
            self.apply_switch()
        if step == 1 and self.leader.moves_first:
            self.reward_state, self.reward_metrics = self.leader.opening(self.player, self.reward_state, self.rng)
            self._reward_moved()
        if step % self.n_pol != 0:
            self.env_step()
        elif self.learner.on_policy:
            self.act()
            self.reward_turn()
            self.update_policy()
        else:
            self.env_step()
            self.reward_turn()

    def env_step(self) -> None:
        """One environment step of the policy player and the policy updates due after it."""
        self.act()
        self.update_policy()

    def act(self) -> None:
        """One environment step of the policy player; a finished episode becomes agent data."""
        result = self.learner.env_step()
        if not self._episode_obs:
            self._episode_obs.append(result.obs)
        self._episode_obs.append(result.next_obs)
        self._episode_acts.append(result.act_norm)
        if result.terminated or result.truncated:
            if result.terminated or len(self._episode_acts) >= self.horizon:
                obs, acts = np.asarray(self._episode_obs), np.asarray(self._episode_acts, np.float32)
                self.finished.append(self.layout.episode(obs, acts, result.terminated, self.horizon))
            self._episode_obs, self._episode_acts = [], []

    def update_policy(self) -> None:
        """The policy player's updates that are due, on batches relabelled by the reward it is paid (the
        current one, or the mean of the last ``--reward.policy-window`` ones)."""
        self.policy_metrics = self.learner.maybe_update(self.policy_reward) or self.policy_metrics

    def reward_turn(self) -> None:
        """The reward player's move at the end of an iteration (nothing if no episode finished)."""
        if not self.finished:
            return
        new = np.concatenate(self.finished)
        self.leader.receive(self.rankings, self.finished, self.rng)
        self.finished = []
        if (turn := self.leader.fit(self.player, self.reward_state, self.rng)) is not None:
            self.reward_state, self.reward_metrics = turn
            self._reward_moved()
        expert = self.rankings.data.expert
        self.reward_metrics["reward/agent"] = self._mean_real_reward(new)
        self.reward_metrics["reward/expert"] = self._mean_real_reward(expert.reshape(-1, expert.shape[-1]))

    def _reward_moved(self) -> None:
        """After a reward fit: stop on a non-finite loss, else pay the policy player the new reward."""
        if not np.isfinite(self.reward_metrics["reward/train_loss"]):
            raise NonFiniteError("the reward loss")
        self.policy_reward = self.averaging.push(self.policy_reward, self.reward_state.params)

    def _mean_real_reward(self, inputs: np.ndarray) -> float:
        """Mean learned reward ``()`` over the inputs ``(N, d)`` that are real states, not absorbing ones."""
        real = inputs[self.layout.is_real(inputs)]
        return self.player.mean_reward(self.reward_state.params, real) if len(real) else float("nan")

    def apply_switch(self) -> None:
        """The non-stationary change (:mod:`rankgame.game.switch`)."""
        assert self.switch is not None
        if self.switch.env_id is not None:
            self.eval_env.close()
            self.eval_env = make_env(self.switch.env_id)
            self.env_id = self.switch.env_id
            self.learner.switch_env(make_env(self.switch.env_id), seed=self.cfg.seed + self.switch.at)
            self.env = self.learner.env
            self._episode_obs, self._episode_acts = [], []
        if self.switch.expert is not None:
            self.rankings.replace_expert(self._switch_inputs, self.rng)
            self.scale = ScoreScale.of(self.switch.expert, self.eval_env, self.cfg.seed)
            # The rewards fit to the old expert leave the policy player's window.
            self.policy_reward = self.averaging.start(self.reward_state.params)
        self.selection.reset()

    # --- what the run harness asks ------------------------------------------------------------
    def can_checkpoint(self, step: int) -> bool:
        return step % self.n_pol == 0

    def evaluate(self) -> dict[str, float]:
        """The deterministic policy's evaluation row (:meth:`~rankgame.scores.ScoreScale.score`) and the
        learned return of its episodes as a share of the expert's (:mod:`rankgame.game.selection`)."""
        seed = self.cfg.seed + EVAL_SEED_OFFSET
        episodes, success_steps = run_episodes(self.eval_env, self.learner.policy(), self.cfg.eval_episodes, seed)
        params, dim = self.reward_state.params, self.layout.dim
        ratio = learned_return_ratio(
            self.player.mean_reward(params, self._inputs(episodes, "evaluation episodes").reshape(-1, dim)),
            self.player.mean_reward(params, self.rankings.data.expert.reshape(-1, dim)),
        )
        return {**self.scale.score(episodes, success_steps), SELECTION_COLUMN: ratio}

    def training_metrics(self) -> dict[str, float]:
        return {**self.reward_metrics, **self.policy_metrics}

    def postfix(self, row: dict[str, float]) -> dict[str, str]:
        return score_postfix(row)

    def save_policies(self, out: Path, step: int, row: dict[str, float]) -> None:
        """Write the current actor for ``rankgame evaluate``, marked as one that reads the absorbing flag
        the game appends to observations, and again as the selected policy when its learned return is
        the best so far (:mod:`rankgame.game.selection`)."""
        names = [POLICY_NAME] + ([SELECTED_POLICY_NAME] if self.selection.improves(row[SELECTION_COLUMN]) else [])
        for name in names:
            self.learner.save_policy(
                out / name,
                self.env_id,
                absorbing_flag=True,
                command=self.command,
                env_steps=step,
                eval_return=row["eval_return"],
            )

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        learner_meta, learner_arrays = self.learner.checkpoint()
        finished = (
            np.stack(self.finished) if self.finished else np.zeros((0, self.horizon, self.layout.dim), np.float32)
        )
        metadata = {
            **learner_meta,
            "game_rng": self.rng.bit_generator.state,
            "reward_metrics": self.reward_metrics,
            "reward_spec": self.reward_spec(),
            "selection_best": self.selection.best,
        }
        arrays = {
            **learner_arrays,
            **flatten_tree("reward", self.reward_state),
            **self.averaging.state_dict(self.policy_reward),
            **self.rankings.state_dict(),
            FINISHED_KEY: finished,
        }
        return metadata, arrays

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        if self.switch is not None and int(metadata["env_steps"]) > self.switch.at:
            self.apply_switch()
        self.learner.restore(metadata, arrays, seed=self.cfg.seed + int(metadata["env_steps"]))
        self.reward_state = unflatten_tree("reward", arrays, self.reward_state)
        self.policy_reward = self.averaging.load(arrays, self.policy_reward, self.reward_state.params)
        self.rankings.load_state_dict(arrays)
        # A checkpoint inside an iteration (a run's last step, a signal) holds the episodes it had finished.
        self.finished = list(arrays[FINISHED_KEY])
        self.rng.bit_generator.state = metadata["game_rng"]
        self.reward_metrics = metadata["reward_metrics"]
        self.selection.best = metadata.get("selection_best")  # absent from checkpoints older than selection

    def reward_spec(self) -> dict[str, Any]:
        """What rebuilds the learned reward outside the game (:mod:`rankgame.reward.export`)."""
        spec = self.learner.spec
        return {
            "env_id": self.env_id,
            "input": self.layout.kind,
            "obs_dim": self.layout.obs_dim,
            "act_dim": self.layout.act_dim,
            "act_low": spec.act_low.tolist(),
            "act_high": spec.act_high.tolist(),
            "hidden_sizes": list(self.cfg.reward.hidden_sizes),
            "columns": None if self.player.net.columns is None else list(self.player.net.columns),
            "spectral_norm": self.cfg.ablation.spectral_norm,
            "r_max": self.cfg.reward.r_max,
            "bound": self.player.loss.bound,
        }
