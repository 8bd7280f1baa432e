"""What TD3's critics and actor minimize, as named pieces of :class:`~rankgame.policy.td3.TD3`.

A :class:`CriticObjective` works in two phases inside one jitted gradient step, as SAC's do
(:mod:`rankgame.policy.critic_objectives`): :meth:`~CriticObjective.prepare` computes what does not
depend on the critics being trained (target values), :meth:`~CriticObjective.loss` is differentiated.
An :class:`ActorObjective` is the actor's loss given the freshly updated critics.

* :class:`ClippedDoubleQ` and :class:`MaxFirstCritic`: TD3's own (Fujimoto et al. 2018): the squared
  Bellman error against ``r + gamma (1 - done) min_i Qbar_i(s', clip(pibar(s') + eps))`` with clipped
  Gaussian smoothing noise ``eps``, and the actor maximizing ``Q_1(s, pi(s))``.
* :class:`DualBellman` and :class:`DualActor`: OPOLO's (Zhu et al. 2020, Eq. 13-14 and their public
  code). The dual of the transition-marginal matching bound is a min-max problem over ``Q`` and ``pi``:
  ``2 alpha (1 - gamma) E_B[min_i Q_i(s, pi(s))] + 1/2 sum_i E_B[(y - Q_i(s, a))^2]`` with
  ``y = r + gamma (1 - done) min_i Qbar_i(s', pi(s'))`` (the online actor, no smoothing noise), where the
  replay buffer's states stand in for the initial-state distribution. The critics minimize it and the
  actor maximizes its first term, regularized toward the actions an inverse action model infers from
  the expert's transitions, ``idm_weight E_E[(g(s, s') - pi(s))^2]``. (The authors' actor loss also
  subtracts a clipped Bellman error whose target is held fixed and whose ``Q(s, a)`` reads the buffer's
  actions: its gradient with respect to the actor is zero, so it is left out.)

With absorbing states (``td3.absorbing``) a transition into ``s_abs`` has the closed-form target value
``r(s_abs) / (1 - gamma)``, and the rows that start in ``s_abs`` (where no action is chosen) count in no
actor term and in no initial-state term.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import jax
import jax.numpy as jnp

from rankgame.absorbing import absorbing_flag, weighted_mean

if TYPE_CHECKING:
    from rankgame.policy.td3 import TD3, Batch, TD3State

Metrics = dict[str, jax.Array]


class CriticObjective(Protocol):
    """The critics' training objective of one TD3 gradient step."""

    def prepare(self, td3: TD3, state: TD3State, batch: Batch, reward_params: Any, key: jax.Array) -> Any:
        """What :meth:`loss` needs that does not depend on the critics' parameters (no gradient flows into it)."""

    def loss(
        self, td3: TD3, critic_params: Any, actor_params: Any, batch: Batch, prepared: Any
    ) -> tuple[jax.Array, tuple[jax.Array, Metrics]]:
        """The loss ``()`` to minimize over ``critic_params`` (the actor's held fixed), with the twin critics'
        ``Q(s, a)`` ``(2, B)`` and metrics."""


class ActorObjective(Protocol):
    """The actor's training objective, given the critics just updated."""

    def loss(self, td3: TD3, actor_params: Any, critic_params: Any, batch: Batch) -> tuple[jax.Array, Metrics]:
        """The loss ``()`` to minimize over ``actor_params``, with metrics."""


def live_rows(td3: TD3, obs: jax.Array) -> jax.Array:
    """``(B,)`` 1.0 on rows of ``obs (B, obs_dim)`` where the policy acts, 0.0 on absorbing states."""
    return 1.0 - absorbing_flag(obs) if td3.absorbing else jnp.ones(obs.shape[0])


def bellman_target(
    td3: TD3, target_critic_params: Any, batch: Batch, next_acts: jax.Array, reward_params: Any
) -> tuple[jax.Array, jax.Array]:
    """``y = r + gamma (1 - done) min_i Qbar_i(s', a')`` ``(B,)`` for the next actions ``a' (B, act_dim)``,
    with the absorbing state's exact value where ``s'`` is ``s_abs``; also the rewards ``r (B,)``."""
    rews = td3.reward_fn(reward_params, batch)
    next_value = jnp.min(td3.critic.apply(target_critic_params, batch["next_obs"], next_acts), axis=0)
    if td3.absorbing:
        into_absorbing = absorbing_flag(batch["next_obs"]) > 0.5
        next_value = jnp.where(into_absorbing, td3.absorbing_value(reward_params), next_value)
    return jax.lax.stop_gradient(rews + td3.config.gamma * (1.0 - batch["dones"]) * next_value), rews


@dataclass(frozen=True)
class ClippedDoubleQ:
    """TD3's critic objective: ``sum_i mean_B (Q_i(s, a) - y)^2`` with the smoothed target of the target actor."""

    def prepare(self, td3: TD3, state: TD3State, batch: Batch, reward_params: Any, key: jax.Array) -> Any:
        cfg = td3.config
        noise = cfg.target_noise * jax.random.normal(key, batch["acts"].shape)
        noise = jnp.clip(noise, -cfg.target_noise_clip, cfg.target_noise_clip)
        next_acts = jnp.clip(td3.policy_action(state.target_actor_params, batch["next_obs"]) + noise, -1.0, 1.0)
        return bellman_target(td3, state.target_critic_params, batch, next_acts, reward_params)

    def loss(
        self, td3: TD3, critic_params: Any, actor_params: Any, batch: Batch, prepared: Any
    ) -> tuple[jax.Array, tuple[jax.Array, Metrics]]:
        target, rews = prepared
        q = td3.critic.apply(critic_params, batch["obs"], batch["acts"])
        return jnp.sum(jnp.mean((q - target) ** 2, axis=1)), (q, {"losses/reward": jnp.mean(rews)})


@dataclass(frozen=True)
class MaxFirstCritic:
    """TD3's actor objective: ``-E_B[Q_1(s, pi(s))]``."""

    def loss(self, td3: TD3, actor_params: Any, critic_params: Any, batch: Batch) -> tuple[jax.Array, Metrics]:
        q = td3.critic.apply(critic_params, batch["obs"], td3.policy_action(actor_params, batch["obs"]))
        return -weighted_mean(q[0], live_rows(td3, batch["obs"])), {}


def initial_value(td3: TD3, critic_params: Any, actor_params: Any, obs: jax.Array) -> jax.Array:
    """``E_B[min_i Q_i(s, pi(s))]`` ``()`` over the live rows of ``obs (B, obs_dim)``: OPOLO's estimate of the
    initial states' value, the buffer's states standing in for the initial-state distribution."""
    q = td3.critic.apply(critic_params, obs, td3.policy_action(actor_params, obs))
    return weighted_mean(jnp.min(q, axis=0), live_rows(td3, obs))


@dataclass(frozen=True)
class DualBellman:
    """OPOLO's critic objective: ``2 alpha (1 - gamma) E_B[min_i Q_i(s, pi(s))] + 1/2 sum_i E_B[(y - Q_i)^2]``,
    ``y = r + gamma (1 - done) min_i Qbar_i(s', pi(s'))`` with the online actor."""

    alpha: float = 0.1

    def prepare(self, td3: TD3, state: TD3State, batch: Batch, reward_params: Any, key: jax.Array) -> Any:
        next_acts = td3.policy_action(state.actor_params, batch["next_obs"])
        return bellman_target(td3, state.target_critic_params, batch, next_acts, reward_params)

    def loss(
        self, td3: TD3, critic_params: Any, actor_params: Any, batch: Batch, prepared: Any
    ) -> tuple[jax.Array, tuple[jax.Array, Metrics]]:
        target, rews = prepared
        q = td3.critic.apply(critic_params, batch["obs"], batch["acts"])
        start = initial_value(td3, critic_params, actor_params, batch["obs"])
        weight = 2.0 * self.alpha * (1.0 - td3.config.gamma)
        bellman = 0.5 * jnp.sum(jnp.mean((target - q) ** 2, axis=1))
        metrics = {"losses/reward": jnp.mean(rews), "losses/initial_value": start, "losses/bellman": bellman}
        return weight * start + bellman, (q, metrics)


@dataclass(frozen=True)
class DualActor:
    """OPOLO's actor objective: ``-2 alpha (1 - gamma) E_B[min_i Q_i(s, pi(s))] + idm_weight E_E[(g - pi(s))^2]``.

    The batch needs ``expert_obs (B, obs_dim)``, expert states, and ``expert_acts (B, act_dim)``, the
    actions ``g(s, s')`` an inverse action model infers from their transitions (the mean over all
    entries, as the authors' ``reduce_mean``)."""

    alpha: float = 0.1
    idm_weight: float = 0.1

    def loss(self, td3: TD3, actor_params: Any, critic_params: Any, batch: Batch) -> tuple[jax.Array, Metrics]:
        start = initial_value(td3, critic_params, actor_params, batch["obs"])
        imitated = td3.policy_action(actor_params, batch["expert_obs"])
        regularizer = jnp.mean((batch["expert_acts"] - imitated) ** 2)
        loss = -2.0 * self.alpha * (1.0 - td3.config.gamma) * start + self.idm_weight * regularizer
        return loss, {"losses/policy_regularizer": regularizer}
