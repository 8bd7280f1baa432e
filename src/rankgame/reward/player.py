"""The reward player: the reward network, its ranking loss and its optimizer (Sec. 4, App. C).

It knows how to take gradient steps on the rankings it is given and how to score a holdout; how
long it trains each turn is the leader's decision (:mod:`rankgame.game.leaders`). Gradient steps
are fused :data:`UPDATES_PER_CALL` at a time into one jitted ``lax.scan`` over pre-sampled batches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax

from rankgame.errors import nonfinite_fields, require
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import Metrics, RankingLoss, bound_reward
from rankgame.reward.nets import RewardNet

if TYPE_CHECKING:
    from rankgame.game.rankings import Rankings
    from rankgame.reward.ranking_data import RankingData

#: Gradient steps fused into one jitted call.
UPDATES_PER_CALL = 8

#: The holdout loss is measured on an evenly strided subset of at most this many agent rows.
HOLDOUT_MAX_ROWS = 4096


@dataclass(frozen=True)
class RewardConfig:
    """Reward network and optimizer (paper, App. C and Table 4)."""

    hidden_sizes: tuple[int, ...] = (64, 64)
    """Hidden layer widths of the reward MLP (ReLU)."""
    lr: float = 1e-3
    """Adam learning rate."""
    weight_decay: float = 1e-4
    """L2 weight decay coefficient (added to the gradient before Adam)."""
    batch_size: int = 1024
    """Ranking inputs per gradient step."""
    r_max: float = 10.0
    """Rewards given to the policy are bounded to [-r_max, r_max]."""
    gradient_penalty: float = 10.0
    """Weight of the gradient penalty of the losses that have one (logistic-gp: dac, dacfo; DAC's 10)."""
    ranking_gradient_penalty: float = 0.0
    """Weight of a gradient penalty at interpolations of agent and expert inputs added to the objective
    of the losses without one of their own (L_k, SL_k, the supremum loss, GAIL's logistic loss): a
    smoother reward; 0 (the paper's) adds none."""
    policy_window: int = 1
    """The policy player is paid the mean of the reward player's last N rewards, one per iteration
    (rankgame.reward.averaging); 1 pays the latest reward, as in the paper."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense together."""
        require(
            [
                (not nonfinite_fields(self), f"reward {', '.join(nonfinite_fields(self))} must be finite"),
                (all(h > 0 for h in self.hidden_sizes), "reward hidden_sizes must be positive"),
                (self.lr > 0 and self.weight_decay >= 0, "reward lr must be positive and weight_decay >= 0"),
                (self.batch_size > 0, "reward batch_size must be positive"),
                (self.r_max > 0, "r_max must be positive"),
                (self.gradient_penalty >= 0, "reward gradient_penalty must be >= 0"),
                (self.ranking_gradient_penalty >= 0, "reward ranking_gradient_penalty must be >= 0"),
                (self.policy_window >= 1, "reward policy_window must be at least 1"),
            ]
        )

    def penalty_weight(self, loss: RankingLoss) -> float:
        """The gradient penalty's weight with ``loss``: its own penalty's, or the ranking losses' (0: none)."""
        return self.gradient_penalty if loss.gradient_penalty else self.ranking_gradient_penalty


@flax.struct.dataclass
class RewardState:
    params: Any
    opt_state: Any


#: A holdout as jitted functions see it: inputs ``(N, d)``, targets, is-expert flags and weights ``(N,)``.
HoldoutBatch = tuple[jax.Array, jax.Array, jax.Array, jax.Array]


class RewardPlayer:
    """Reward network, its ranking loss and its optimizer.

    Args:
        layout: the reward inputs (see :class:`~rankgame.reward.inputs.InputLayout`); decides how SAC
            batches become reward inputs.
        loss: the ranking loss (an entry of :data:`rankgame.reward.losses.LOSSES`); it also decides how
            the reward handed to the policy is bounded.
        config: network and optimizer settings.
        rankings: what the reward fits; its objective combines the loss over its chains.
        columns: entries of a reward input the network reads (default: all of them).
        spectral_norm: divide every layer by its spectral norm (App. D's regularizer ablation).
    """

    def __init__(
        self,
        layout: InputLayout,
        loss: RankingLoss,
        config: RewardConfig,
        rankings: Rankings,
        columns: tuple[int, ...] | None = None,
        spectral_norm: bool = False,
    ) -> None:
        config.validate()
        self.layout = layout
        self.loss = loss
        self.config = config
        self.rankings = rankings
        self.net = RewardNet(config.hidden_sizes, columns, spectral_norm)
        self.tx = optax.chain(optax.add_decayed_weights(config.weight_decay), optax.adam(config.lr))
        self._objective = rankings.objective(self.net.apply, loss, config.r_max, config.penalty_weight(loss))
        self._update = jax.jit(self._update_many, donate_argnums=(0,))
        self._holdout_loss = jax.jit(self._weighted_loss)
        self._mean_reward = jax.jit(self._weighted_mean_reward)

    def init(self, key: jax.Array) -> RewardState:
        params = self.net.init(key, jnp.zeros((1, self.layout.dim), jnp.float32))
        return RewardState(params=params, opt_state=self.tx.init(params))

    def reward(self, params: Any, features: jax.Array) -> jax.Array:
        """Bounded rewards ``(B,)`` for reward inputs ``(B, d)``."""
        return bound_reward(self.net.apply(params, features), self.config.r_max, self.loss.bound)

    def reward_fn(self, params: Any, batch: dict[str, jax.Array]) -> jax.Array:
        """The reward function handed to SAC: relabels a batch ``(B,)`` with the current reward."""
        return self.reward(params, self.layout.from_batch(batch))

    def _weighted_mean_reward(self, params: Any, features: jax.Array, weights: jax.Array) -> jax.Array:
        return jnp.sum(self.reward(params, features) * weights) / jnp.sum(weights)

    def mean_reward(self, params: Any, features: np.ndarray) -> float:
        """Mean bounded reward ``()`` over inputs ``(N, d)``, N > 0 (jitted; padded to few shapes)."""
        (padded,), weights = _pad_to_power_of_two([features])
        return float(self._mean_reward(params, padded, weights))

    def _update_many(
        self, state: RewardState, batches: tuple[Any, ...]
    ) -> tuple[RewardState, tuple[jax.Array, Metrics]]:
        """Gradient steps over ``n`` stacked batches of :meth:`Rankings.sample`; mean loss and metrics."""

        def step(carry: RewardState, batch: tuple[Any, ...]) -> tuple[RewardState, tuple[jax.Array, Metrics]]:
            (loss, metrics), grads = jax.value_and_grad(self._objective, has_aux=True)(carry.params, batch)
            updates, opt_state = self.tx.update(grads, carry.opt_state, carry.params)
            return RewardState(optax.apply_updates(carry.params, updates), opt_state), (loss, metrics)

        state, (losses, metrics) = jax.lax.scan(step, state, batches)
        return state, (jnp.mean(losses), jax.tree.map(jnp.mean, metrics))

    def fit_steps(
        self, state: RewardState, n_updates: int, rng: np.random.Generator
    ) -> tuple[RewardState, float, dict[str, float]]:
        """About ``n_updates`` gradient steps (rounded up to whole fused calls) on the rankings; returns
        the new state, the mean training loss and the loss's own metrics (means, ``reward/``-prefixed)."""
        losses, metrics = [], []
        for _ in range(max(1, math.ceil(n_updates / UPDATES_PER_CALL))):
            batches = self.rankings.sample(rng, UPDATES_PER_CALL, self.config.batch_size)
            state, (loss, step_metrics) = self._update(state, batches)
            losses.append(loss)
            metrics.append(step_metrics)
        means = jax.tree.map(lambda *values: float(np.mean(values)), *jax.device_get(metrics))
        return state, float(np.mean(jax.device_get(losses))), {f"reward/{k}": v for k, v in means.items()}

    def holdout_batch(self, data: RankingData) -> HoldoutBatch | None:
        """The agent-vs-expert holdout (at most ``HOLDOUT_MAX_ROWS`` rows and all their mixtures), padded
        to a power of two so that jitted functions see few shapes; None when there is no holdout."""
        inputs, targets, is_expert = data.holdout(HOLDOUT_MAX_ROWS)
        if len(inputs) == 0:
            return None
        (inputs, targets, is_expert), weights = _pad_to_power_of_two([inputs, targets, is_expert])
        return tuple(jnp.asarray(x) for x in (inputs, targets, is_expert, weights))  # type: ignore[return-value]

    def _weighted_loss(
        self, params: Any, inputs: jax.Array, targets: jax.Array, is_expert: jax.Array, weights: jax.Array
    ) -> jax.Array:
        return self.loss(self.net.apply(params, inputs), targets, is_expert, weights, self.config.r_max)[0]

    def holdout_loss(self, params: Any, holdout: HoldoutBatch | None) -> float:
        """The ranking loss ``()`` on a :meth:`holdout_batch`; NaN when there is no holdout."""
        return float("nan") if holdout is None else float(self._holdout_loss(params, *holdout))


def _pad_to_power_of_two(arrays: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray]:
    """Zero-pad arrays of equal leading size N > 0 to the next power of two, so that jitted functions
    see few distinct shapes; returns the padded arrays and weights ``(N_padded,)`` (1 real, 0 padding)."""
    n = len(arrays[0])
    pad = (1 << (n - 1).bit_length()) - n
    padded = [np.concatenate([a, np.zeros((pad, *a.shape[1:]), a.dtype)]) for a in arrays]
    weights = np.concatenate([np.ones(n, np.float32), np.zeros(pad, np.float32)])
    return padded, weights
