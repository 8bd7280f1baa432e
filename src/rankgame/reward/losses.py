"""Ranking losses of the reward player, as pure functions ``loss(raw, targets, ...) -> (scalar, metrics)``.

* :func:`regression_ranking_loss` is L_k (Eq. 2) and its shaped, generalized form SL_k (App. B.1,
  Eq. 8): every input is regressed to the target of the behavior it came from. With only agent
  (target 0) and expert (target k) groups of equal size it is exactly L_k / 2; with the auto
  mixtures it is SL_k.
* :func:`snippet_regression_loss` regresses the summed reward of a snippet of ``l`` steps of an
  offline trajectory to ``k_i l`` (App. B.3), scaled by ``1 / l^2``.
* :func:`supremum_loss` is the loss of the IMIT ablation (App. D.3): maximize the gap between the
  bounded reward on expert and on agent inputs, ``-(E_E[r] - E_pi[r])``.
* :func:`weighted_sum` combines losses, e.g. ``alpha L_k(online) + (1 - alpha) L_k(offline)`` (Eq. 6).

Regression losses act on the *raw* network output, not the clipped reward: the targets lie inside
the reward bound, so an output beyond the bound still gets a gradient pulling it back, instead of
the zero gradient a clip would give (a reward stuck at the bound forever).
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp

Metrics = dict[str, jax.Array]


def regression_ranking_loss(
    raw: jax.Array, targets: jax.Array, weights: jax.Array | None = None
) -> tuple[jax.Array, Metrics]:
    """SL_k: mean squared error between reward outputs and their ranking targets.

    Args:
        raw: ``(B,)`` unbounded reward outputs.
        targets: ``(B,)`` target of each input's behavior (0 for the agent, k for the expert, and
            the schedule's k_p for mixture p).
        weights: optional ``(B,)`` non-negative weights (e.g. 0 for padding rows).
    Returns:
        the loss and ``{"mse": ...}``.
    """
    sq = (raw - targets) ** 2
    loss = jnp.mean(sq) if weights is None else jnp.sum(weights * sq) / jnp.maximum(jnp.sum(weights), 1e-08)
    return loss, {"mse": loss}


def snippet_regression_loss(raw: jax.Array, targets: jax.Array) -> tuple[jax.Array, Metrics]:
    """Squared error of each snippet's summed reward against ``k_i l``, divided by ``l^2``.

    Args:
        raw: ``(S, l)`` unbounded reward outputs along each of S snippets of length l.
        targets: ``(S,)`` per-step target ``k_i`` of the behavior each snippet came from.
    Returns:
        ``mean_s ((sum_t raw[s, t] - l k_s) / l)^2``, the squared error of the snippet's mean reward,
        and ``{"snippet_mse": ...}``.
    """
    length = raw.shape[-1]
    loss = jnp.mean(((jnp.sum(raw, axis=-1) - length * targets) / length) ** 2)
    return loss, {"snippet_mse": loss}


def supremum_loss(
    bounded: jax.Array, is_expert: jax.Array, weights: jax.Array | None = None
) -> tuple[jax.Array, Metrics]:
    """IMIT loss: ``-(mean r(expert) - mean r(agent))`` for bounded rewards.

    Args:
        bounded: ``(B,)`` rewards already squashed into ``[-R_max, R_max]``.
        is_expert: ``(B,)`` 1.0 for expert inputs, 0.0 for agent inputs; both groups must be present.
        weights: optional ``(B,)`` non-negative weights (e.g. 0 for padding rows, which then count
            in neither group's mean).
    """
    w = jnp.ones_like(bounded) if weights is None else weights
    expert_w, agent_w = is_expert * w, (1.0 - is_expert) * w
    gap = jnp.sum(expert_w * bounded) / jnp.maximum(jnp.sum(expert_w), 1e-08) - jnp.sum(
        agent_w * bounded
    ) / jnp.maximum(jnp.sum(agent_w), 1e-08)
    return -gap, {"gap": gap}


def weighted_sum(terms: Sequence[tuple[float, tuple[jax.Array, Metrics]]]) -> tuple[jax.Array, Metrics]:
    """``sum_i w_i loss_i`` with each term's metrics kept under ``term{i}/``."""
    total = jnp.zeros(())
    metrics: Metrics = {}
    for i, (weight, (loss, term_metrics)) in enumerate(terms):
        total = total + weight * loss
        metrics[f"term{i}/loss"] = loss
        metrics.update({f"term{i}/{k}": v for k, v in term_metrics.items()})
    return total, metrics
