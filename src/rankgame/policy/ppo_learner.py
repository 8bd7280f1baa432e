"""The on-policy player in an environment: acting, the rollout being collected, and PPO updates.

:class:`PPOLearner` owns one environment, one rollout of ``rollout_steps`` transitions and one
:class:`~rankgame.policy.ppo.PPO`. It is driven exactly like :class:`~rankgame.policy.learner.SACLearner`:
``env_step()`` once per environment step, then ``maybe_update(reward_params)``, which runs one PPO
update (``epochs`` x ``rollout_steps / minibatch_size`` gradient steps in one jitted call) each time
the rollout is full, and starts a new rollout. Its actor is a SAC actor: :meth:`PPOLearner.save_policy`
writes it with :func:`rankgame.policy.io.save_policy`, so ``load_policy`` and ``rankgame evaluate``
read it unchanged. There is no observation normalization (nothing besides the actor to save).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import gymnasium as gym
import jax
import numpy as np

from rankgame.absorbing import absorbing_obs, flag_obs
from rankgame.checkpoint import flatten_tree, unflatten_tree
from rankgame.envs.make import env_spec
from rankgame.envs.rollout import PolicyFn, to_env_action
from rankgame.errors import NonFiniteError, RankGameError
from rankgame.policy.io import save_policy
from rankgame.policy.learner import StepResult, make_policy_fn
from rankgame.policy.ppo import PPO, PPOConfig, PPOState
from rankgame.policy.sac import SAC, RewardFn, SACConfig, env_reward

#: Prefix of the rollout's arrays in a checkpoint (``rollout/obs``, ...).
ROLLOUT_PREFIX = "rollout"


class PPOLearner:
    """PPO acting in ``env`` and learning from the rollouts it collects.

    Args:
        env: a continuous-control environment (see :func:`rankgame.envs.make.make_env`).
        config: PPO hyperparameters.
        seed: seeds parameters and minibatch shuffling (``jax.random``), the acting noise (NumPy) and
            the environment's first reset; the same seed gives the same numbers.
        reward_fn: relabels each full rollout with rewards (default: the environment's reward, which
            the rollout always keeps).
        absorbing: DAC-style absorbing states (see :mod:`rankgame.absorbing`): observations get an
            absorbing flag, a terminal step is stored as ``s -> s_abs``, and PPO values what follows
            it at exactly ``r(s_abs) / (1 - gamma)`` with the current reward.

    Attributes:
        state: the :class:`~rankgame.policy.ppo.PPOState` (``state.actor_params`` is a SAC actor's tree).
        rollout: the rollout being collected, arrays of ``rollout_steps`` rows (see
            :class:`~rankgame.policy.ppo.PPO`), of which the first ``rollout_pos`` are filled.
        sac: a SAC built only to describe the actor to :mod:`rankgame.policy.io` (its ``obs_dim``,
            ``act_dim`` and hidden sizes) and to act through :func:`make_policy_fn`; never trained.

    A non-finite action or observation, or a non-finite PPO loss, raises
    :class:`~rankgame.errors.NonFiniteError`.
    """

    on_policy = True
    """PPO updates on the rollout of its current policy only."""
    log_columns: tuple[str, ...] = ("losses/entropy", "losses/approx_kl", "losses/clip_fraction")
    """Metrics with a column of their own in ``metrics.csv`` besides the game's ``LOG_COLUMNS``."""

    def __init__(
        self,
        env: gym.Env,
        config: PPOConfig,
        seed: int,
        reward_fn: RewardFn = env_reward,
        absorbing: bool = False,
    ) -> None:
        self.env = env
        self.spec = env_spec(env)
        self.config = config
        self.absorbing = absorbing
        obs_dim, act_dim = self.spec.obs_dim + int(absorbing), self.spec.act_dim
        self.ppo = PPO(obs_dim, act_dim, config, reward_fn=reward_fn, absorbing=absorbing)
        self.sac = SAC(obs_dim, act_dim, SACConfig(hidden_sizes=config.hidden_sizes))
        self.state: PPOState = self.ppo.init(jax.random.key(seed))
        shapes = {"obs": (obs_dim,), "acts": (act_dim,), "pre_tanh": (act_dim,), "next_obs": (obs_dim,)}
        names = ("obs", "acts", "pre_tanh", "logp", "next_obs", "dones", "truncs", "rews")
        steps = config.rollout_steps
        self.rollout = {name: np.zeros((steps, *shapes.get(name, ())), np.float32) for name in names}
        self.rollout_pos = 0
        self.rng = np.random.default_rng(seed)
        self.env_steps = 0
        self._obs, _ = env.reset(seed=seed)
        self._episode_return = 0.0

    def env_step(self) -> StepResult:
        """Sample an action from the current policy, step the environment and store the transition.

        Raises ``RuntimeError`` if the rollout is full (call :meth:`maybe_update` after every step)."""
        if self.rollout_pos >= self.config.rollout_steps:
            raise RuntimeError("the rollout is full: call maybe_update() after every env_step()")
        noise = self.rng.standard_normal((1, self.spec.act_dim)).astype(np.float32)
        acts, pre_tanh, logp = self.ppo.act(self.state.actor_params, self._policy_obs(self._obs)[None], noise)
        act_norm, pre_tanh, logp = np.asarray(acts)[0], np.asarray(pre_tanh)[0], float(np.asarray(logp)[0])
        if not (np.all(np.isfinite(act_norm)) and np.all(np.isfinite(pre_tanh)) and np.isfinite(logp)):
            raise NonFiniteError("the policy's action")
        act = to_env_action(act_norm, self.spec.act_low, self.spec.act_high)
        next_obs, rew, terminated, truncated, _ = self.env.step(act)
        if not (np.all(np.isfinite(next_obs)) and np.isfinite(rew)):
            raise NonFiniteError(f"the observation or reward of {self.spec.env_id}")
        terminated, truncated = bool(terminated), bool(truncated)
        stored_next = absorbing_obs(self.spec.obs_dim) if self.absorbing and terminated else self._policy_obs(next_obs)
        row = {
            "obs": self._policy_obs(self._obs),
            "acts": act_norm,
            "pre_tanh": pre_tanh,
            "logp": logp,
            "next_obs": stored_next,
            "dones": float(terminated),
            "truncs": float(truncated and not terminated),
            "rews": float(rew),
        }
        for name, value in row.items():
            self.rollout[name][self.rollout_pos] = value
        self.rollout_pos += 1
        result = StepResult(self._obs, act_norm, next_obs, terminated, truncated)
        self.env_steps += 1
        self._episode_return += float(rew)
        if terminated or truncated:
            result.episode_return = self._episode_return
            self._obs, _ = self.env.reset()
            self._episode_return = 0.0
        else:
            self._obs = next_obs
        return result

    def maybe_update(self, reward_params: Any = None) -> dict[str, float] | None:
        """Run the PPO update if the rollout is full (every ``rollout_steps`` environment steps), relabelling
        it with ``reward_fn(reward_params, ...)``; its metrics if it ran, else None."""
        if self.rollout_pos < self.config.rollout_steps:
            return None
        self.state, metrics = self.ppo.update(self.state, self.rollout, reward_params)
        self.rollout_pos = 0
        values = {key: float(value) for key, value in metrics.items()}
        for name in ("actor", "critic"):
            if not np.isfinite(values[f"losses/{name}"]):
                raise NonFiniteError(f"the PPO {name} loss")
        return values

    def policy(self, deterministic: bool = True) -> PolicyFn:
        """The current policy as ``obs (obs_dim,) -> action (act_dim,)`` in environment units (without the
        absorbing flag, which is appended when needed); deterministic: ``tanh(mean)``. A stochastic policy
        draws from its own generator, never from the learner's."""
        rng = np.random.default_rng([self.env_steps, 1])
        low, high = self.spec.act_low, self.spec.act_high
        return make_policy_fn(self.sac, self.state.actor_params, low, high, rng, deterministic, self.absorbing)

    def save_policy(self, path: str | Path, env_id: str, **metadata: Any) -> Path:
        """Write the current actor with :func:`rankgame.policy.io.save_policy` (readable by ``load_policy``
        and ``rankgame evaluate``), marked with ``absorbing_flag`` and ``policy_player="ppo"``."""
        metadata = {"absorbing_flag": self.absorbing, **metadata}
        if bool(metadata["absorbing_flag"]) != self.absorbing:
            raise ValueError(
                f"absorbing_flag={metadata['absorbing_flag']} but this learner has absorbing={self.absorbing}"
            )
        metadata.setdefault("policy_player", "ppo")
        metadata.setdefault("ppo_config", dataclasses.asdict(self.config))
        params = jax.device_get(self.state.actor_params)
        return save_policy(path, self.sac, params, env_id, self.spec.act_low, self.spec.act_high, **metadata)

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON metadata and arrays that :meth:`restore` turns back into this learner's state, the part of
        the rollout collected so far included."""
        metadata = {
            "env_steps": self.env_steps,
            "rollout_pos": self.rollout_pos,
            "learner_rng": self.rng.bit_generator.state,
        }
        rollout = {f"{ROLLOUT_PREFIX}/{name}": array[: self.rollout_pos].copy() for name, array in self.rollout.items()}
        return metadata, {**flatten_tree("ppo", self.state), **rollout}

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray], seed: int) -> None:
        """Inverse of :meth:`checkpoint`. The interrupted episode is lost: its last stored step becomes a
        cut (bootstrapped with the critic, like a time limit) and a new episode starts from ``seed``."""
        self.state = unflatten_tree("ppo", arrays, self.state)
        pos = int(metadata["rollout_pos"])
        if not 0 <= pos <= self.config.rollout_steps:
            raise RankGameError(
                f"the checkpoint's rollout holds {pos} steps; rollout_steps is {self.config.rollout_steps}"
            )
        for name, array in self.rollout.items():
            saved = arrays[f"{ROLLOUT_PREFIX}/{name}"]
            if saved.shape != (pos, *array.shape[1:]):
                raise RankGameError(
                    f"the checkpoint does not match this configuration ({name} has shape {saved.shape})"
                )
            array[:pos] = saved
        self.rollout_pos = pos
        self.env_steps = int(metadata["env_steps"])
        self.rng.bit_generator.state = metadata["learner_rng"]
        self._start_episode(seed)

    def switch_env(self, env: gym.Env, seed: int) -> None:
        """Act in ``env`` from now on (a task with the same spaces whose dynamics or reward changed); the
        episode in progress is abandoned (a cut in the rollout) and a new one starts from ``seed``."""
        spec = env_spec(env)
        if (spec.obs_dim, spec.act_dim) != (self.spec.obs_dim, self.spec.act_dim):
            raise ValueError(
                f"{spec.env_id} has obs_dim={spec.obs_dim}, act_dim={spec.act_dim}; "
                f"{self.spec.env_id} has obs_dim={self.spec.obs_dim}, act_dim={self.spec.act_dim}"
            )
        self.env.close()
        self.env, self.spec = env, spec
        self._start_episode(seed)

    def _start_episode(self, seed: int) -> None:
        """Abandon the episode in progress: end it in the rollout (unless it just ended) and reset from ``seed``."""
        last = self.rollout_pos - 1
        if last >= 0 and self.rollout["dones"][last] == 0.0:
            self.rollout["truncs"][last] = 1.0
        self._obs, _ = self.env.reset(seed=seed)
        self._episode_return = 0.0

    def _policy_obs(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, np.float32)
        return flag_obs(obs) if self.absorbing else obs
