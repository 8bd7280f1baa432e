"""Ranking losses of the reward player, registered by name in :data:`LOSSES`, each with its reward bound.

A :class:`RankingLoss` maps the raw reward outputs of a batch to a scalar loss and its metrics, and
declares how the reward handed to the policy is bounded to ``[-r_max, r_max]``:

* ``regression``: L_k (Eq. 2) and its shaped, generalized form SL_k (App. B.1, Eq. 8), every input
  regressed to the target of the behavior it came from (:func:`regression_ranking_loss`). With only
  agent (target 0) and expert (target k) groups of equal size it is exactly L_k / 2; with the auto
  mixtures it is SL_k. It acts on the *raw* output, not the bounded reward: the targets lie inside
  the bound, so an output beyond it still gets a gradient pulling it back, instead of the zero
  gradient a clip would give. The policy sees the hard clip.
* ``supremum``: the loss of the IMIT ablation (App. D.3), maximize the gap between the bounded reward
  on expert and on agent inputs, ``-(E_E[r] - E_pi[r])`` (:func:`supremum_loss`). The bound must be
  inside the loss, so it is the smooth ``r_max tanh(x / r_max)``, whose gradient stays alive, and the
  policy sees that same bounded reward.
* ``logistic``: the discriminator of GAIL / GAIfO (Ho & Ermon 2016; Torabi et al. 2018), binary
  cross-entropy with the raw output as the logit of ``D = P(expert | x)`` (:func:`logistic_loss`). The
  policy is paid ``-log(1 - D) = softplus(x)`` (bound ``softplus``, capped at ``r_max``), GAIL's
  positive form, which never makes ending an episode attractive.
* ``logistic-gp``: the same discriminator with DAC's gradient penalty (Kostrikov et al. 2019, after
  Gulrajani et al. 2017): ``coef E[(||grad_x D(x_hat)|| - 1)^2]`` at random interpolations ``x_hat``
  of agent and expert inputs (:func:`gradient_penalty`). The policy is paid DAC's
  ``log D - log(1 - D) = x``, clipped to ``[-r_max, r_max]``; with absorbing states the sign of this
  reward is no bias (Kostrikov et al., Sec. 4.2).
* ``logistic-gp-softplus``: the discriminator with the gradient penalty, paying GAIL's
  ``-log(1 - D) = softplus(x)`` (capped at ``r_max``): OPOLO's (Zhu et al. 2020).
* ``f-divergence``: f-IRL's reward objective (Ni et al. 2020), the covariance over trajectories of the
  summed rewards with the summed ``h_f`` of an estimated density ratio (:func:`f_divergence_surrogate`),
  for the marginal rankings (:mod:`rankgame.game.rankings`). The policy sees the clipped reward.
* ``bradley-terry``: T-REX's loss on pairs of snippets of ranked trajectories (Brown et al. 2019), the
  Luce-Shepard choice probability ``P(b > w) = exp R_b / (exp R_b + exp R_w)`` of the summed rewards
  of the better and the worse snippet (:func:`bradley_terry_loss`); a pairwise loss, used by the
  pairwise rankings (:mod:`rankgame.game.rankings`). The policy sees the clipped per-state reward.

Also here: :func:`snippet_regression_loss` (App. B.3) for snippets of offline trajectories, and
:func:`weighted_sum`, which combines losses as in Eq. 6. A new loss is a new entry of :data:`LOSSES`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import jax
import jax.numpy as jnp

Metrics = dict[str, jax.Array]
Bound = Literal["clip", "tanh", "softplus"]

#: ``(raw (B,), targets (B,), is_expert (B,), weights (B,), r_max) -> (loss (), metrics)``.
LossFn = Callable[[jax.Array, jax.Array, jax.Array, jax.Array, float], tuple[jax.Array, Metrics]]


def bound_reward(raw: jax.Array, r_max: float, bound: Bound) -> jax.Array:
    """Map raw outputs ``(B,)`` into ``[-r_max, r_max]``: a hard ``clip``, a smooth ``tanh``, or the
    discriminator reward ``softplus(raw) = -log(1 - sigmoid(raw))`` capped at ``r_max``."""
    if bound == "clip":
        return jnp.clip(raw, -r_max, r_max)
    if bound == "softplus":
        return jnp.minimum(jax.nn.softplus(raw), r_max)
    return r_max * jnp.tanh(raw / r_max)


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


def logistic_loss(
    logits: jax.Array, is_expert: jax.Array, weights: jax.Array | None = None
) -> tuple[jax.Array, Metrics]:
    """Discriminator loss: binary cross-entropy of ``D = sigmoid(logits)`` labelled 1 on expert inputs.

    ``E_E[-log D] + E_pi[-log(1 - D)] = E_E[softplus(-x)] + E_pi[softplus(x)]``, each side its own mean,
    so the two behaviors weigh equally whatever their share of the batch. Its minimizer over a free
    function is ``D* = rho_E / (rho_E + rho_pi)`` (Goodfellow et al. 2014, Prop. 1).

    Args:
        logits: ``(B,)`` raw discriminator outputs.
        is_expert: ``(B,)`` 1.0 for expert inputs, 0.0 for agent inputs.
        weights: optional ``(B,)`` non-negative weights (0 for padding rows).
    Returns:
        the loss and ``{"accuracy": share of rows on the right side of D = 1/2, "expert_d": mean D on
        expert rows}``.
    """
    w = jnp.ones_like(logits) if weights is None else weights
    expert_w, agent_w = is_expert * w, (1.0 - is_expert) * w
    n_expert, n_agent = jnp.maximum(jnp.sum(expert_w), 1e-08), jnp.maximum(jnp.sum(agent_w), 1e-08)
    loss = (
        jnp.sum(expert_w * jax.nn.softplus(-logits)) / n_expert + jnp.sum(agent_w * jax.nn.softplus(logits)) / n_agent
    )
    correct = jnp.where(is_expert > 0.5, logits > 0, logits < 0).astype(logits.dtype)
    metrics = {
        "accuracy": jnp.sum(w * correct) / jnp.maximum(jnp.sum(w), 1e-08),
        "expert_d": jnp.sum(expert_w * jax.nn.sigmoid(logits)) / n_expert,
    }
    return loss, metrics


def gradient_penalty(raw_fn: Callable[[jax.Array], jax.Array], points: jax.Array) -> jax.Array:
    """``E[(||grad_x raw(x)|| - 1)^2]`` over ``points (B, d)`` (Gulrajani et al. 2017; DAC's regularizer).

    ``raw_fn`` maps inputs ``(B, d)`` to outputs ``(B,)`` row by row, so the gradient of their sum with
    respect to the inputs holds each row's own input gradient.
    """
    grads = jax.grad(lambda x: jnp.sum(raw_fn(x)))(points)
    norms = jnp.sqrt(jnp.sum(grads**2, axis=-1) + 1e-12)
    return jnp.mean((norms - 1.0) ** 2)


def bradley_terry_loss(better: jax.Array, worse: jax.Array) -> tuple[jax.Array, Metrics]:
    """T-REX's loss: ``-log P(better > worse)`` with ``P = exp R_b / (exp R_b + exp R_w)``.

    Args:
        better: ``(S,)`` summed raw rewards of the preferred snippets.
        worse: ``(S,)`` summed raw rewards of the snippets ranked below them.
    Returns:
        ``mean_s softplus(R_w - R_b)`` and ``{"accuracy": share of pairs with R_b > R_w}``.
    """
    loss = jnp.mean(jax.nn.softplus(worse - better))
    return loss, {"accuracy": jnp.mean((better > worse).astype(better.dtype))}


Divergence = Literal["fkl", "rkl", "js"]

#: f-IRL's ``h_f`` of each divergence as a function of the log density ratio ``l = log rho_E / rho_pi``,
#: up to an additive constant (which the covariance of :func:`f_divergence_surrogate` cancels): forward KL
#: ``-rho_E / rho_pi``, reverse KL ``-l``, Jensen-Shannon ``-log(1 + rho_E / rho_pi)`` (Ni et al. 2020, Table 1).
H_FUNCTIONS: dict[str, Callable[[jax.Array], jax.Array]] = {
    "fkl": lambda log_ratio: -jnp.exp(log_ratio),
    "rkl": lambda log_ratio: -log_ratio,
    "js": lambda log_ratio: -jax.nn.softplus(log_ratio),
}


def f_divergence_surrogate(
    reward_sums: jax.Array, h_sums: jax.Array, weights: jax.Array, horizon: int
) -> tuple[jax.Array, Metrics]:
    """f-IRL's reward objective (Ni et al. 2020, Thm. 4.1): a loss whose gradient is that of the
    f-divergence between the expert's and the agent's state marginals with respect to the reward,
    ``(1 / T) Cov_tau(sum_t h_f(s_t), sum_t grad r(s_t))``.

    Args:
        reward_sums: ``(N,)`` summed rewards ``sum_t r(s_t)`` of N trajectories of length ``T``.
        h_sums: ``(N,)`` their summed ``h_f(log rho_E(s_t) / rho_pi(s_t))`` (held fixed).
        weights: ``(N,)`` 1 for a trajectory, 0 for padding.
        horizon: ``T``.
    Returns:
        the weighted sample covariance ``(mean(A B) - mean(A) mean(B)) / T`` of ``A = h_sums`` and
        ``B = reward_sums``, and ``{"h_spread": std of A / T}``.
    """
    n = jnp.maximum(jnp.sum(weights), 1.0)
    mean_h = jnp.sum(weights * h_sums) / n
    mean_r = jnp.sum(weights * reward_sums) / n
    loss = (jnp.sum(weights * h_sums * reward_sums) / n - mean_h * mean_r) / horizon
    spread = jnp.sqrt(jnp.sum(weights * (h_sums - mean_h) ** 2) / n) / horizon
    return loss, {"h_spread": spread}


def weighted_sum(terms: Sequence[tuple[float, tuple[jax.Array, Metrics]]]) -> tuple[jax.Array, Metrics]:
    """``sum_i w_i loss_i`` with each term's metrics kept under ``term{i}/``."""
    total = jnp.zeros(())
    metrics: Metrics = {}
    for i, (weight, (loss, term_metrics)) in enumerate(terms):
        total = total + weight * loss
        metrics[f"term{i}/loss"] = loss
        metrics.update({f"term{i}/{k}": v for k, v in term_metrics.items()})
    return total, metrics


@dataclass(frozen=True)
class RankingLoss:
    """A ranking loss of the reward player and the bound it puts on the reward the policy sees.

    Attributes:
        fn: the loss on one batch (see :data:`LossFn`); rows of weight 0 count in no term.
        bound: how rewards handed to the policy are bounded (:func:`bound_reward`).
        regresses_targets: whether the loss regresses rewards to per-behavior targets, so that offline
            ranked chains (the pref rankings, Eq. 6) can be fit with the same targets.
        gradient_penalty: whether the objective adds :func:`gradient_penalty` at interpolated inputs,
            weighted by ``--reward.gradient-penalty``.
        pairwise: a loss on pairs of snippets, ``fn(better (S,), worse (S,))`` (see
            :func:`bradley_terry_loss`), for the pairwise rankings; else a loss on one batch of inputs.
        marginal: a loss on whole trajectories against density-ratio estimates (see
            :func:`f_divergence_surrogate`), for the marginal rankings.
        log_columns: the metrics of this loss that ``metrics.csv`` gets a column for (all of them reach
            TensorBoard).
    """

    fn: LossFn
    bound: Bound
    regresses_targets: bool
    gradient_penalty: bool = False
    pairwise: bool = False
    marginal: bool = False
    log_columns: tuple[str, ...] = ()

    def __call__(
        self, raw: jax.Array, targets: jax.Array, is_expert: jax.Array, weights: jax.Array, r_max: float
    ) -> tuple[jax.Array, Metrics]:
        return self.fn(raw, targets, is_expert, weights, r_max)


def _regression(
    raw: jax.Array, targets: jax.Array, _is_expert: jax.Array, weights: jax.Array, _r_max: float
) -> tuple[jax.Array, Metrics]:
    return regression_ranking_loss(raw, targets, weights)


def _supremum(
    raw: jax.Array, _targets: jax.Array, is_expert: jax.Array, weights: jax.Array, r_max: float
) -> tuple[jax.Array, Metrics]:
    return supremum_loss(bound_reward(raw, r_max, "tanh"), is_expert, weights)


def _logistic(
    raw: jax.Array, _targets: jax.Array, is_expert: jax.Array, weights: jax.Array, _r_max: float
) -> tuple[jax.Array, Metrics]:
    return logistic_loss(raw, is_expert, weights)


def _bradley_terry(better: jax.Array, worse: jax.Array, *_unused: Any) -> tuple[jax.Array, Metrics]:
    return bradley_terry_loss(better, worse)


#: The ranking losses by name (the ``loss`` column of :data:`rankgame.game.methods.METHODS`).
LOSSES: dict[str, RankingLoss] = {
    "regression": RankingLoss(_regression, bound="clip", regresses_targets=True),
    "supremum": RankingLoss(_supremum, bound="tanh", regresses_targets=False),
    "logistic": RankingLoss(_logistic, "softplus", regresses_targets=False, log_columns=("reward/accuracy",)),
    "logistic-gp": RankingLoss(
        _logistic,
        "clip",
        regresses_targets=False,
        gradient_penalty=True,
        log_columns=("reward/accuracy", "reward/gradient_penalty"),
    ),
    "logistic-gp-softplus": RankingLoss(
        _logistic,
        "softplus",
        regresses_targets=False,
        gradient_penalty=True,
        log_columns=("reward/accuracy", "reward/gradient_penalty"),
    ),
    "bradley-terry": RankingLoss(
        _bradley_terry,  # type: ignore[arg-type]
        "clip",
        regresses_targets=False,
        pairwise=True,
        log_columns=("reward/accuracy",),
    ),
    "f-divergence": RankingLoss(
        f_divergence_surrogate,  # type: ignore[arg-type]
        "clip",
        regresses_targets=False,
        marginal=True,
        log_columns=("reward/ratio_loss",),
    ),
}
