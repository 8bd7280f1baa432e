"""What SAC's critic is trained to minimize, as named pieces of :class:`~rankgame.policy.sac.SAC`.

A :class:`CriticObjective` works in two phases inside one jitted gradient step: :meth:`prepare` computes
everything that does not depend on the critic being trained (sampled actions, target-network values),
and :meth:`loss` is the function of the critic's parameters that is differentiated. The actor and
temperature updates are SAC's whatever the objective (the actor maximizes ``min_i Q_i - alpha log pi``).

* :class:`SoftBellman`: SAC's own objective, the squared soft Bellman error against a reward that labels
  every batch (``reward_fn``), with the absorbing state's closed-form value (:mod:`rankgame.absorbing`).
* :class:`InverseSoftQ`: IQ-Learn's (Garg et al. 2021, Eq. 10 and its chi-squared form): no reward at
  all; the critic itself is the reward model, ``r_Q(s, a) = Q(s, a) - gamma V(s')``, fit so that it is
  high on the expert's transitions and its soft value is low on every state. It needs batches that mix
  agent and expert rows (``is_expert``, see :func:`rankgame.policy.buffer.mix_demonstrations`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol

import jax
import jax.numpy as jnp

from rankgame.absorbing import absorbing_flag, weighted_mean

if TYPE_CHECKING:
    from rankgame.policy.sac import SAC, Batch, SACState

Metrics = dict[str, jax.Array]


class CriticObjective(Protocol):
    """The critic's training objective of one SAC gradient step."""

    def prepare(
        self, sac: SAC, state: SACState, batch: Batch, reward_params: Any, key: jax.Array, alpha: jax.Array
    ) -> Any:
        """What :meth:`loss` needs that does not depend on the critic's parameters (no gradient flows into it)."""

    def loss(
        self, sac: SAC, critic_params: Any, batch: Batch, prepared: Any
    ) -> tuple[jax.Array, tuple[jax.Array, Metrics]]:
        """The loss ``()`` to minimize over ``critic_params``, with the twin critics' ``Q(s, a)`` ``(2, B)``
        and metrics."""


def sampled_value(
    sac: SAC, critic_params: Any, actor_params: Any, obs: jax.Array, noise: jax.Array, alpha: jax.Array
) -> jax.Array:
    """One-sample soft value ``V(s) = min_i Q_i(s, a~) - alpha log pi(a~|s)``, ``(B,)`` for ``obs (B, obs_dim)``
    and standard normal ``noise (B, act_dim)`` (``a~`` is the reparameterized policy action)."""
    from rankgame.policy.sac import squashed_gaussian_sample

    mean, log_std = sac.actor.apply(actor_params, obs)
    acts, logp = squashed_gaussian_sample(mean, log_std, noise)
    return jnp.min(sac.critic.apply(critic_params, obs, acts), axis=0) - alpha * logp


@dataclass(frozen=True)
class SoftBellman:
    """SAC's critic objective: ``sum_i mean_B (Q_i(s, a) - y)^2`` with the soft Bellman target
    ``y = r + gamma (1 - done) (min_i Qbar_i(s', a') - alpha log pi(a'|s'))``, ``a' ~ pi(s')``, ``r`` from
    ``sac.reward_fn``; with absorbing states, ``y`` of a transition into ``s_abs`` uses its exact value."""

    def prepare(
        self, sac: SAC, state: SACState, batch: Batch, reward_params: Any, key: jax.Array, alpha: jax.Array
    ) -> Any:
        rews = sac.reward_fn(reward_params, batch)
        next_value = sampled_value(
            sac,
            state.target_critic_params,
            state.actor_params,
            batch["next_obs"],
            jax.random.normal(key, (batch["next_obs"].shape[0], sac.act_dim)),
            alpha,
        )
        if sac.absorbing:
            into_absorbing = absorbing_flag(batch["next_obs"]) > 0.5
            next_value = jnp.where(into_absorbing, sac.absorbing_value(reward_params), next_value)
        target = jax.lax.stop_gradient(rews + sac.config.gamma * (1.0 - batch["dones"]) * next_value)
        return target, rews

    def loss(
        self, sac: SAC, critic_params: Any, batch: Batch, prepared: Any
    ) -> tuple[jax.Array, tuple[jax.Array, Metrics]]:
        target, rews = prepared
        q = sac.critic.apply(critic_params, batch["obs"], batch["acts"])
        return jnp.sum(jnp.mean((q - target) ** 2, axis=1)), (q, {"losses/reward": jnp.mean(rews)})


def inverse_soft_q_loss(
    q: jax.Array,
    value: jax.Array,
    discounted_next: jax.Array,
    expert_weights: jax.Array,
    variant: Literal["v0", "value"],
    chi2_weight: float,
    gamma: float,
    row_weights: jax.Array | None = None,
) -> tuple[jax.Array, jax.Array]:
    """IQ-Learn's objective to minimize (Garg et al. 2021, Eq. 10 with the chi-squared regularizer).

    Args:
        q: ``(C, B)`` each of ``C`` critics' ``Q(s, a)`` on the rows.
        value: ``(B,)`` the soft value ``V(s)`` of each row's state (gradient flows through it).
        discounted_next: ``(B,)`` ``gamma (1 - done) V(s')`` (held fixed).
        expert_weights: ``(B,)`` each row's weight in the expert's expectations ``E_E`` (1 on expert rows
            and 0 on agent rows of a sampled batch; occupancies in a tabular problem).
        variant: ``v0``, with ``(1 - gamma) E_E[V(s)]``, or ``value``, with ``E_{E+pi}[V(s) - gamma V(s')]``.
        chi2_weight: weight of ``E_{E+pi}[r^2]``.
        gamma: the discount.
        row_weights: ``(B,)`` each row's weight in ``E_{E+pi}``, the expectations over all rows (default:
            the plain mean, as over a sampled batch).
    Returns:
        the loss ``mean_c(-E_E[r_c] + chi2_weight E_{E+pi}[r_c^2]) + value term`` and the implied rewards
        ``r = q - discounted_next`` ``(C, B)``.
    """
    implied = q - discounted_next
    rows = jnp.ones_like(value) if row_weights is None else row_weights
    if variant == "value":
        value_term = weighted_mean(value - discounted_next, rows)
    else:
        value_term = (1.0 - gamma) * weighted_mean(value, expert_weights)
    per_critic = -weighted_mean(implied, expert_weights) + chi2_weight * weighted_mean(implied**2, rows)
    return jnp.mean(per_critic) + value_term, implied


@dataclass(frozen=True)
class InverseSoftQ:
    """IQ-Learn's critic objective (Garg et al. 2021), for each twin critic ``Q_i`` (averaged over both):

    ``-E_E[r_i] + value + chi2_weight E_{E+pi}[r_i^2]``, with ``r_i = Q_i(s, a) - gamma (1 - done) Vbar(s')``
    (the reward the critic implies; ``Vbar`` from the target critics, as the authors' ``use_target``) and

    * ``value`` variant: ``E_{E+pi}[V(s) - gamma (1 - done) Vbar(s')]``, the telescoped form of
      ``(1 - gamma) E_{rho_0}[V(s_0)]`` that holds under any policy's state distribution;
    * ``v0`` variant: ``(1 - gamma) E_E[V(s)]``, the initial-state term with the expert's states standing
      in for ``rho_0``, as in the authors' code.

    ``V`` is the one-sample soft value of the online critics (:func:`sampled_value`). The first term uses
    ``phi(x) = x`` and the last is the chi-squared regularizer ``1 / (4 alpha_chi)`` of the authors'
    ``regularize`` option (their ``alpha_chi = 0.5``: weight 0.5), taken over expert and agent rows alike
    (:func:`inverse_soft_q_loss`).

    The batch needs ``is_expert (B,)``; ``dones`` are true terminations (no absorbing states).
    """

    variant: Literal["v0", "value"] = "v0"
    chi2_weight: float = 0.5

    def prepare(
        self, sac: SAC, state: SACState, batch: Batch, reward_params: Any, key: jax.Array, alpha: jax.Array
    ) -> Any:
        k_now, k_next = jax.random.split(key)
        shape = (batch["obs"].shape[0], sac.act_dim)
        next_value = sampled_value(
            sac,
            state.target_critic_params,
            state.actor_params,
            batch["next_obs"],
            jax.random.normal(k_next, shape),
            alpha,
        )
        discounted_next = jax.lax.stop_gradient(sac.config.gamma * (1.0 - batch["dones"]) * next_value)
        return discounted_next, jax.random.normal(k_now, shape), state.actor_params, alpha

    def loss(
        self, sac: SAC, critic_params: Any, batch: Batch, prepared: Any
    ) -> tuple[jax.Array, tuple[jax.Array, Metrics]]:
        discounted_next, noise, actor_params, alpha = prepared
        is_expert = batch["is_expert"]
        q = sac.critic.apply(critic_params, batch["obs"], batch["acts"])
        value = sampled_value(sac, critic_params, actor_params, batch["obs"], noise, alpha)
        loss, implied = inverse_soft_q_loss(
            q, value, discounted_next, is_expert, self.variant, self.chi2_weight, sac.config.gamma
        )
        metrics = {
            "losses/expert_reward": jnp.mean(weighted_mean(implied, is_expert)),
            "losses/agent_reward": jnp.mean(weighted_mean(implied, 1.0 - is_expert)),
            "losses/value": jnp.mean(value),
        }
        return loss, (q, metrics)
