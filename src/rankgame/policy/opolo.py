"""OPOLO's policy player (Zhu, Lin, Dai & Zhou 2020, "Off-Policy Imitation Learning from Observations").

TD3 (:mod:`rankgame.policy.td3`) whose critics and actor play OPOLO's dual objectives
(:class:`~rankgame.policy.td3_objectives.DualBellman`, :class:`~rankgame.policy.td3_objectives.DualActor`),
paid by the game's discriminator on state transitions (``--method opolo``: GAIL's reward
``-log(1 - D(s, s'))`` with DAC's gradient penalty), with the actor regularized toward the actions an
inverse action model ``g(s, s')`` infers from the expert's transitions. The inverse model
(:class:`~rankgame.baselines.inverse_dynamics.InverseDynamics`) learns from the agent's own replay
buffer, whose actions are known: ``idm_pretrain_steps`` gradient steps when TD3's updates begin, then
``idm_steps`` every ``idm_every`` environment steps, each fit relabelling the expert's transitions.

Settings follow the authors' public code: the inverse model is a 256-256 MLP trained by the mean squared
error with an L2 penalty of 1e-3 and Adam at 3e-4, on batches of TD3's size; per task
(:data:`AUTHORS_SETTINGS`) ``alpha``, ``idm_weight`` and the learning rate are 0.01, 0.01 and 1e-4 on
Hopper and 0.1, 0.1 and 3e-4 elsewhere. Differences: the inverse model reads ReLU features of
standardized ``(s, s' - s)`` instead of tanh features of ``(s, s')``, observations carry no time feature,
and episodes end in absorbing states as in every game here instead of bootstrapping through terminations.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import jax
import numpy as np

from rankgame.absorbing import absorbing_flag, flag_obs
from rankgame.baselines.inverse_dynamics import InverseDynamics
from rankgame.checkpoint import flatten_tree, unflatten_tree
from rankgame.data.trajectories import Trajectory
from rankgame.envs.rollout import PolicyFn, to_env_action
from rankgame.errors import nonfinite_fields, require
from rankgame.policy.critic_objectives import CriticObjective
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import SAC, RewardFn, SACConfig
from rankgame.policy.td3 import TD3, TD3Config
from rankgame.policy.td3_objectives import DualActor, DualBellman

#: The authors' per-task values ``(alpha, idm_weight, lr)``, by task family; every other task gets
#: :data:`OTHER_TASKS`.
AUTHORS_SETTINGS: dict[str, tuple[float, float, float]] = {"Hopper": (0.01, 0.01, 1e-4)}
OTHER_TASKS = (0.1, 0.1, 3e-4)

#: The inverse model's network, L2 penalty and learning rate (the authors').
IDM_HIDDEN = (256, 256)
IDM_WEIGHT_DECAY = 1e-3
IDM_LR = 3e-4


@dataclass(frozen=True)
class OPOLOConfig:
    """OPOLO's objectives and inverse action model (opolo only; its TD3 settings are --td3.*)."""

    alpha: float | None = None
    """Weight of the initial-state value in the dual objectives, 2 alpha (1 - gamma) E[Q(s, pi(s))];
    default: the authors' value for the task (0.01 on Hopper, 0.1 elsewhere)."""
    idm_weight: float | None = None
    """Weight of the actor's regularizer E_expert[(g(s, s') - pi(s))^2]; default: the authors' value for
    the task (0.01 on Hopper, 0.1 elsewhere)."""
    idm_every: int = 500
    """Environment steps between fits of the inverse action model."""
    idm_steps: int = 50
    """Gradient steps of each fit of the inverse action model."""
    idm_pretrain_steps: int = 2500
    """Gradient steps of its first fit, when TD3's updates begin."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense."""
        require(
            [
                (not nonfinite_fields(self), "opolo weights must be finite"),
                (self.alpha is None or self.alpha >= 0.0, "opolo.alpha must be >= 0"),
                (self.idm_weight is None or self.idm_weight >= 0.0, "opolo.idm_weight must be >= 0"),
                (self.idm_every > 0, "opolo.idm_every must be positive"),
                (self.idm_steps >= 0 and self.idm_pretrain_steps >= 0, "opolo idm steps must be >= 0"),
            ]
        )

    def resolved(self, env_id: str) -> tuple[float, float, float]:
        """``(alpha, idm_weight, default lr)`` on task ``env_id``."""
        family = env_id.split("/")[-1].split("-")[0]
        alpha, idm_weight, lr = AUTHORS_SETTINGS.get(family, OTHER_TASKS)
        return (
            alpha if self.alpha is None else self.alpha,
            idm_weight if self.idm_weight is None else self.idm_weight,
            lr,
        )


def expert_transitions(trajectories: tuple[Trajectory, ...] | list[Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    """The expert's state transitions ``(obs, next_obs)``, each ``(N, obs_dim)`` with ``N = sum T_i``."""
    obs = np.concatenate([t.obs[:-1] for t in trajectories]).astype(np.float32)
    next_obs = np.concatenate([t.obs[1:] for t in trajectories]).astype(np.float32)
    return obs, next_obs


class OPOLOLearner(SACLearner):
    """TD3 with OPOLO's objectives and inverse action model, acting in ``env``; driven like
    :class:`~rankgame.policy.learner.SACLearner` (``env_step()``, then ``maybe_update(reward_params)``).

    Args:
        env: the task.
        config: TD3's settings; an unset ``lr`` gets the authors' value for the task.
        opolo: the objectives' weights and the inverse model's schedule.
        seed: seeds everything random.
        reward_fn: the game's learned reward.
        expert: the expert trajectories whose state transitions the inverse model labels.
        env_id: the task's id, for the per-task settings.
    """

    log_columns = ("losses/initial_value", "losses/bellman", "losses/policy_regularizer", "losses/idm")

    def __init__(
        self,
        env: gym.Env,
        config: TD3Config,
        opolo: OPOLOConfig,
        seed: int,
        reward_fn: RewardFn,
        expert: tuple[Trajectory, ...] | list[Trajectory],
        env_id: str,
    ) -> None:
        self.alpha, self.idm_weight, default_lr = opolo.resolved(env_id)
        self.opolo = opolo
        super().__init__(env, config.with_lr(default_lr), seed, reward_fn, store_env_reward=False, absorbing=True)
        spec = self.spec
        self._reader = SAC(spec.obs_dim + 1, spec.act_dim, SACConfig(hidden_sizes=self.config.hidden_sizes))
        self.expert_obs, self.expert_next_obs = expert_transitions(expert)
        self.expert_policy_obs = flag_obs(self.expert_obs)
        self.inverse = InverseDynamics(
            spec.obs_dim, spec.act_dim, IDM_HIDDEN, IDM_LR, IDM_WEIGHT_DECAY, self.config.batch_size, chunk=50
        )
        self.idm_state = self.inverse.init(jax.random.fold_in(jax.random.key(seed), 3))
        self.expert_acts = np.zeros((len(self.expert_obs), spec.act_dim), np.float32)
        self.idm_metrics: dict[str, float] = {}
        self._idm_started = False

    def _make_agent(self, obs_dim: int, reward_fn: RewardFn, critic_objective: CriticObjective) -> TD3:
        return TD3(
            obs_dim,
            self.spec.act_dim,
            self.config,
            reward_fn,
            absorbing=True,
            critic_objective=DualBellman(self.alpha),
            actor_objective=DualActor(self.alpha, self.idm_weight),
        )

    @property
    def sac(self) -> SAC:
        """A SAC with TD3's actor network, whose deterministic action ``tanh(mean)`` is TD3's: the saved
        policy file is the same as every other method's."""
        return self._reader

    def maybe_update(self, reward_params: Any = None) -> dict[str, float] | None:
        """Fit the inverse model when due (relabelling the expert's transitions), then TD3's due updates."""
        if self.env_steps >= self.config.update_after:
            if not self._idm_started:
                self._idm_started = True
                self._fit_inverse(self.opolo.idm_pretrain_steps)
            elif self.env_steps % self.opolo.idm_every == 0:
                self._fit_inverse(self.opolo.idm_steps)
        metrics = super().maybe_update(reward_params)
        return None if metrics is None else {**metrics, **self.idm_metrics}

    def _fit_inverse(self, n_steps: int) -> None:
        """``n_steps`` gradient steps of the inverse model on the buffer's real transitions (not those into
        or out of the absorbing state), standardized by their statistics; then relabel the expert."""
        data = {name: array[: len(self.buffer)] for name, array in self.buffer.data.items()}
        real = (absorbing_flag(data["obs"]) < 0.5) & (absorbing_flag(data["next_obs"]) < 0.5)
        if n_steps == 0 or not real.any():
            return
        obs, next_obs, acts = data["obs"][real, :-1], data["next_obs"][real, :-1], data["acts"][real]
        self.idm_state = self.inverse.with_statistics(self.idm_state, obs, next_obs)
        self.idm_state, loss = self.inverse.fit(self.idm_state, obs, acts, next_obs, self.rng, n_steps)
        self.expert_acts = np.asarray(self.inverse.predict(self.idm_state, self.expert_obs, self.expert_next_obs))
        self.idm_metrics = {"losses/idm": loss}

    def _complete_batches(self, batches: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each batch ``(n, B, ...)`` gets ``B`` expert states with their inferred actions (``expert_obs``,
        ``expert_acts``), drawn uniformly with replacement: the actor regularizer's rows."""
        n, batch_size = batches["obs"].shape[:2]
        idx = self.rng.integers(0, len(self.expert_obs), size=(n, batch_size))
        return {**batches, "expert_obs": self.expert_policy_obs[idx], "expert_acts": self.expert_acts[idx]}

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        metadata, arrays = super().checkpoint()
        metadata = {**metadata, "idm_metrics": self.idm_metrics}
        return metadata, {**arrays, **flatten_tree("idm", self.idm_state), "opolo/expert_acts": self.expert_acts}

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray], seed: int) -> None:
        super().restore(metadata, arrays, seed)
        self.idm_state = unflatten_tree("idm", arrays, self.idm_state)
        self.expert_acts = np.asarray(arrays["opolo/expert_acts"], np.float32)
        self.idm_metrics = dict(metadata["idm_metrics"])
        self._idm_started = self.env_steps >= self.config.update_after  # the first fit ran in that step

    def policy(self, deterministic: bool = True) -> PolicyFn:
        """The current actor as ``obs (obs_dim,) -> action (act_dim,)`` in environment units; not
        deterministic: with TD3's Gaussian exploration noise."""
        if deterministic:
            return super().policy(True)
        actor_params, rng, low, high = self.state.actor_params, self.rng, self.spec.act_low, self.spec.act_high

        def noisy(obs: np.ndarray) -> np.ndarray:
            noise = rng.standard_normal((1, self.spec.act_dim)).astype(np.float32)
            flagged = flag_obs(np.asarray(obs, np.float32))[None]
            return to_env_action(np.asarray(self.agent.act(actor_params, flagged, noise))[0], low, high)

        return noisy
