"""The policy player in an environment: acting, storing transitions and fused SAC updates.

:class:`SACLearner` owns one environment, one replay buffer and one :class:`~rankgame.policy.sac.SAC`.
Both the expert trainer (environment reward) and the ranking game (learned reward) drive it the
same way: ``env_step()`` once per environment step, then ``maybe_update(reward_params)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import jax
import numpy as np

from rankgame.absorbing import absorbing_obs, flag_obs
from rankgame.checkpoint import flatten_tree, unflatten_tree
from rankgame.envs.make import env_spec
from rankgame.envs.rollout import PolicyFn, to_env_action
from rankgame.errors import NonFiniteError
from rankgame.policy.buffer import ReplayBuffer, mix_demonstrations
from rankgame.policy.critic_objectives import CriticObjective, SoftBellman
from rankgame.policy.sac import SAC, RewardFn, SACConfig, SACState, env_reward


@dataclass
class StepResult:
    """What one environment step produced; ``episode_return`` is set when an episode ended."""

    obs: np.ndarray
    act_norm: np.ndarray  # SAC's normalized box [-1, 1]
    next_obs: np.ndarray
    terminated: bool
    truncated: bool
    episode_return: float | None = None


class SACLearner:
    """SAC acting in ``env`` and learning from its replay buffer.

    Args:
        env: a continuous-control environment (see :func:`rankgame.envs.make.make_env`).
        config: SAC hyperparameters.
        seed: seeds parameters (``jax.random``), exploration noise and batch sampling (NumPy) and
            the environment's first reset; the same seed gives the same numbers.
        reward_fn: labels sampled batches with rewards (default: the environment's reward).
        store_env_reward: keep the environment reward in the buffer (needed by :func:`env_reward`).
        absorbing: DAC-style absorbing states (see :mod:`rankgame.absorbing`): observations get
            an absorbing flag, and a terminal step is stored as ``s -> s_abs`` followed by the
            self-loop ``s_abs -> s_abs``, neither with a terminal mask; SAC values ending an
            episode at exactly ``r(s_abs) / (1 - gamma)`` with the current learned reward.
        critic_objective: what SAC's critic minimizes (default: the soft Bellman error,
            :mod:`rankgame.policy.critic_objectives`).
        demonstrations: expert transitions ``(N, ...)`` with the buffer's fields (``obs``, ``acts`` in the
            normalized box, ``next_obs``, ``dones``); when given, every batch is half agent, half expert rows
            (:func:`~rankgame.policy.buffer.mix_demonstrations`), as IQ-Learn trains.

    A non-finite action or observation, or a non-finite SAC loss, raises
    :class:`~rankgame.errors.NonFiniteError` before it reaches the environment or the buffer's users.
    """

    on_policy = False
    """SAC learns from its replay buffer, not only from the data of the current policy."""
    log_columns: tuple[str, ...] = ()
    """Metrics with a column of their own in ``metrics.csv`` besides the game's ``LOG_COLUMNS``."""

    def __init__(
        self,
        env: gym.Env,
        config: SACConfig,
        seed: int,
        reward_fn: RewardFn = env_reward,
        store_env_reward: bool = True,
        absorbing: bool = False,
        critic_objective: CriticObjective | None = None,
        demonstrations: dict[str, np.ndarray] | None = None,
    ) -> None:
        self.env = env
        self.spec = env_spec(env)
        self.config = config
        self.absorbing = absorbing
        sac_obs_dim = self.spec.obs_dim + int(absorbing)
        self.agent = self._make_agent(sac_obs_dim, reward_fn, critic_objective or SoftBellman())
        self.demonstrations = demonstrations
        self.state: SACState = self.agent.init(jax.random.key(seed))
        extras = ("rews",) if store_env_reward else ()
        self.buffer = ReplayBuffer(config.buffer_size, sac_obs_dim, self.spec.act_dim, extras=extras)
        self.rng = np.random.default_rng(seed)
        self.env_steps = 0
        self._obs, _ = env.reset(seed=seed)
        self._episode_return = 0.0
        self._updates_owed = 0.0

    def _make_agent(self, obs_dim: int, reward_fn: RewardFn, critic_objective: CriticObjective) -> Any:
        """The learning algorithm, with ``init``, ``act(actor_params, obs, noise)`` and ``update(state, batches,
        reward_params)``: SAC here; a subclass may build another (OPOLO's TD3)."""
        return SAC(obs_dim, self.spec.act_dim, self.config, reward_fn, self.absorbing, critic_objective)

    @property
    def sac(self) -> SAC:
        """The SAC whose actor network the saved and returned policies run (the agent itself here)."""
        return self.agent

    def env_step(self) -> StepResult:
        """Take one action (uniformly random during the first ``start_steps``) and store the transition."""
        if self.env_steps < self.config.start_steps:
            act_norm = self.rng.uniform(-1.0, 1.0, self.spec.act_dim).astype(np.float32)
        else:
            noise = self.rng.standard_normal((1, self.spec.act_dim)).astype(np.float32)
            obs = self._policy_obs(self._obs)[None]
            act_norm = np.asarray(self.agent.act(self.state.actor_params, obs, noise))[0]
            if not np.all(np.isfinite(act_norm)):
                raise NonFiniteError("the policy's action")
        act = to_env_action(act_norm, self.spec.act_low, self.spec.act_high)
        next_obs, rew, terminated, truncated, _ = self.env.step(act)
        if not (np.all(np.isfinite(next_obs)) and np.isfinite(rew)):
            raise NonFiniteError(f"the observation or reward of {self.spec.env_id}")
        self._store(self._obs, act_norm, next_obs, bool(terminated), float(rew))
        result = StepResult(self._obs, act_norm, next_obs, bool(terminated), bool(truncated))
        self.env_steps += 1
        self._episode_return += float(rew)
        if terminated or truncated:
            result.episode_return = self._episode_return
            self._obs, _ = self.env.reset()
            self._episode_return = 0.0
        else:
            self._obs = next_obs
        return result

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON metadata and arrays that :meth:`restore` turns back into this learner's state."""
        metadata = {
            "env_steps": self.env_steps,
            "updates_owed": self._updates_owed,
            "learner_rng": self.rng.bit_generator.state,
        }
        return metadata, {**flatten_tree("sac", self.state), **self.buffer.state_dict()}

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray], seed: int) -> None:
        """Inverse of :meth:`checkpoint`. The interrupted episode is lost: a new one starts from ``seed``."""
        self.state = unflatten_tree("sac", arrays, self.state)
        self.buffer.load_state_dict(arrays)
        self.env_steps = int(metadata["env_steps"])
        self._updates_owed = float(metadata["updates_owed"])
        self.rng.bit_generator.state = metadata["learner_rng"]
        self._obs, _ = self.env.reset(seed=seed)
        self._episode_return = 0.0

    def switch_env(self, env: gym.Env, seed: int) -> None:
        """Act in ``env`` from now on (a task with the same spaces whose dynamics or reward changed);
        the episode in progress is abandoned and a new one starts from ``seed``. The replay buffer is kept."""
        spec = env_spec(env)
        if (spec.obs_dim, spec.act_dim) != (self.spec.obs_dim, self.spec.act_dim):
            raise ValueError(
                f"{spec.env_id} has obs_dim={spec.obs_dim}, act_dim={spec.act_dim}; "
                f"{self.spec.env_id} has obs_dim={self.spec.obs_dim}, act_dim={self.spec.act_dim}"
            )
        self.env.close()
        self.env, self.spec = env, spec
        self._obs, _ = env.reset(seed=seed)
        self._episode_return = 0.0

    def _policy_obs(self, obs: np.ndarray) -> np.ndarray:
        return flag_obs(np.asarray(obs, np.float32)) if self.absorbing else obs

    def _store(self, obs: np.ndarray, act_norm: np.ndarray, next_obs: np.ndarray, terminated: bool, rew: float) -> None:
        extra = {"rews": rew} if "rews" in self.buffer.data else {}
        if not self.absorbing:
            self.buffer.add(obs=obs, acts=act_norm, next_obs=next_obs, dones=float(terminated), **extra)
            return
        if not terminated:
            self.buffer.add(obs=flag_obs(obs), acts=act_norm, next_obs=flag_obs(next_obs), dones=0.0, **extra)
            return
        s_abs = absorbing_obs(self.spec.obs_dim)
        self.buffer.add(obs=flag_obs(obs), acts=act_norm, next_obs=s_abs, dones=0.0, **extra)
        no_act = np.zeros(self.spec.act_dim, np.float32)
        self.buffer.add(obs=s_abs, acts=no_act, next_obs=s_abs, dones=0.0, **({"rews": 0.0} if extra else {}))

    def maybe_update(self, reward_params: Any = None) -> dict[str, float] | None:
        """Run the fused SAC updates that are due after this environment step; metrics if any ran.

        Every ``update_every`` steps (once ``update_after`` steps are collected) this performs
        ``update_every * updates_per_step`` gradient steps in one jitted call.
        """
        cfg = self.config
        if self.env_steps < cfg.update_after or self.env_steps % cfg.update_every != 0:
            return None
        self._updates_owed += cfg.update_every * cfg.updates_per_step
        n_updates = int(self._updates_owed)
        if n_updates == 0:
            return None
        self._updates_owed -= n_updates
        batches = self._complete_batches(self.buffer.sample(self.rng, n_updates, cfg.batch_size))
        self.state, metrics = self.agent.update(self.state, batches, reward_params)
        values = {key: float(value) for key, value in metrics.items()}
        for name in ("critic", "actor", "alpha"):
            if not np.isfinite(values.get(f"losses/{name}", 0.0)):
                algorithm = type(self.agent).__name__
                raise NonFiniteError(
                    f"the {algorithm} {name} loss" if name != "alpha" else f"the {algorithm} temperature"
                )
        return values

    def _complete_batches(self, batches: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The sampled buffer batches ``(n, B, ...)`` with what the agent's objectives read besides: the
        demonstrations' half, when there are any (:func:`~rankgame.policy.buffer.mix_demonstrations`)."""
        if self.demonstrations is None:
            return batches
        return mix_demonstrations(batches, self.demonstrations, self.rng)

    def save_policy(self, path: Path, env_id: str, **metadata: Any) -> Path:
        """Write the current actor to ``path`` for ``rankgame evaluate`` (:func:`rankgame.policy.io.save_policy`)."""
        from rankgame.policy.io import save_policy

        params = jax.device_get(self.state.actor_params)
        return save_policy(path, self.sac, params, env_id, self.spec.act_low, self.spec.act_high, **metadata)

    def policy(self, deterministic: bool = True) -> PolicyFn:
        """The current policy as ``obs (obs_dim,) -> action (act_dim,)`` in environment units."""
        actor_params = self.state.actor_params
        low, high = self.spec.act_low, self.spec.act_high
        return make_policy_fn(self.sac, actor_params, low, high, self.rng, deterministic, self.absorbing)


def make_policy_fn(
    sac: SAC,
    actor_params: Any,
    act_low: np.ndarray,
    act_high: np.ndarray,
    rng: np.random.Generator | None = None,
    deterministic: bool = True,
    absorbing_flag: bool = False,
) -> PolicyFn:
    """Wrap actor parameters as a :data:`PolicyFn` (mean action when deterministic).

    With ``absorbing_flag`` (an actor trained by the ranking game) a zero absorbing flag is appended
    to every environment observation ``(obs_dim,)`` before the actor sees it.
    """
    zeros = np.zeros((1, sac.act_dim), np.float32)
    rng = rng if rng is not None else np.random.default_rng(0)

    def policy(obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, np.float32)
        obs = flag_obs(obs) if absorbing_flag else obs
        noise = zeros if deterministic else rng.standard_normal((1, sac.act_dim)).astype(np.float32)
        act = np.asarray(sac.act(actor_params, obs[None], noise))[0]
        return to_env_action(act, act_low, act_high)

    return policy
