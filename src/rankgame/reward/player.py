"""The reward player: fits the reward network to the ranking dataset with a budget or early stopping.

Gradient steps are fused ``chunk`` at a time into one jitted ``lax.scan`` over pre-sampled batches.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax

from rankgame.errors import nonfinite_fields, require
from rankgame.policy.sac import Batch
from rankgame.reward.losses import (
    Metrics,
    regression_ranking_loss,
    snippet_regression_loss,
    supremum_loss,
    weighted_sum,
)
from rankgame.reward.nets import Bound, RewardInput, RewardNet, batch_features, bound_reward
from rankgame.reward.offline_rankings import OfflineRankings
from rankgame.reward.ranking_data import RankingData

RankingLoss = Literal["regression", "supremum"]

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
    holdout_fraction: float = 0.1
    """Share of agent rows held out of training, at most 0.5: the holdout budget (PAL's) stops fitting
    when their loss stops improving; the passes budget (RAL's) only logs their loss."""
    patience: int = 3
    """Epochs without holdout improvement before fitting stops (holdout budget)."""
    min_improvement: float = 0.01
    """Relative decrease of the holdout loss that counts as an improvement (holdout budget)."""
    max_epochs: int = 50
    """Upper bound on epochs per fit (holdout budget)."""
    budget: Literal["leader", "holdout", "passes"] = "leader"
    """How long the reward trains each iteration: holdout (until the holdout loss stops improving),
    passes (n_rew = ral_passes |D| / batch_size gradient steps), or leader: the paper's choice for the
    leader, holdout for PAL and passes for RAL (Table 4; the other pairings are App. D's ablation)."""
    ral_passes: float = 1.0
    """Passes over the agent data per iteration with the passes budget (RAL's, by default): n_rew =
    ral_passes |D| / batch_size gradient steps, |D| = the agent rows counted by ``budget_rows`` (each
    step draws one mixture per sampled row)."""
    budget_rows: Literal["real", "all"] = "real"
    """Which agent rows size both budgets (a holdout epoch, and |D| of the passes budget): ``real``
    counts the real agent states only (at least H per holdout epoch), ``all`` also the absorbing rows
    that pad early-terminated trajectories to H, as the authors' code does. Batches are drawn from all
    rows either way, so with many short episodes ``all`` trains up to H / (episode length) times more."""
    holdout_rows: Literal["all", "real"] = "all"
    """Which agent rows may be held out: ``all`` (the shuffled ``holdout_fraction`` of every row), or
    ``real``, real agent states only. Absorbing rows repeat one state, and so does every row's
    expert end of the chain, so with ``all`` early, short episodes fill the holdout with inputs the
    reward also trains on."""
    pref_weight: float = 0.3
    """Weight of the offline rankings' loss in the (pref) methods, ``1 - alpha`` in Eq. 6 (the paper's
    Table 4: offline rankings loss weight 0.3); the agent-vs-expert ranking gets the rest."""
    spectral_norm: bool = False
    """Divide every layer's weights by their spectral norm (a regularizer the paper compares auto
    rankings with, App. D; off in the paper's method)."""
    snippet_length: int = 10
    """Steps per snippet of an offline trajectory whose summed reward is regressed to k_i l (pref)."""
    chunk: int = 8
    """Gradient steps fused into one jitted call."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense together."""
        checks = [
            (not nonfinite_fields(self), f"reward {', '.join(nonfinite_fields(self))} must be finite"),
            (all(h > 0 for h in self.hidden_sizes), "reward hidden_sizes must be positive"),
            (self.lr > 0 and self.weight_decay >= 0, "reward lr must be positive and weight_decay >= 0"),
            (self.batch_size > 0 and self.chunk > 0, "reward batch_size and chunk must be positive"),
            (self.r_max > 0, "r_max must be positive"),
            (0.0 <= self.holdout_fraction <= 0.5, "holdout_fraction must lie in [0, 0.5]"),
            (self.patience > 0 and self.max_epochs > 0, "patience and max_epochs must be positive"),
            (self.budget in ("leader", "holdout", "passes"), "budget must be leader, holdout or passes"),
            (self.ral_passes > 0, "ral_passes must be positive"),
            (self.budget_rows in ("real", "all"), "budget_rows must be real or all"),
            (self.holdout_rows in ("real", "all"), "holdout_rows must be real or all"),
            (0.0 <= self.min_improvement < 1.0, "min_improvement must lie in [0, 1)"),
            (0.0 <= self.pref_weight <= 1.0, "pref_weight must lie in [0, 1]"),
            (self.snippet_length > 0, "snippet_length must be positive"),
        ]
        require(checks)


@flax.struct.dataclass
class RewardState:
    params: Any
    opt_state: Any


class RewardPlayer:
    """Reward network, its ranking loss and its optimizer.

    Args:
        feature_dim: size of one reward input (see :func:`rankgame.reward.nets.feature_dim`).
        reward_input: ``s``, ``ss`` or ``sa``; decides how SAC batches become reward inputs.
        loss: ``regression`` (L_k / SL_k) or ``supremum`` (IMIT ablation).
        columns: entries of a reward input the network reads (default: all of them).
        offline: offline rankings of the (pref) methods, fit alongside the agent-vs-expert ranking
            with weight ``config.pref_weight`` (Eq. 6); only with the regression loss.
    """

    def __init__(
        self,
        feature_dim: int,
        reward_input: RewardInput,
        loss: RankingLoss,
        config: RewardConfig,
        columns: Sequence[int] | None = None,
        offline: OfflineRankings | None = None,
    ) -> None:
        config.validate()
        if offline is not None and loss != "regression":
            raise ValueError("offline rankings need the regression ranking loss")
        self.offline = offline
        self.config = config
        self.feature_dim = feature_dim
        self.reward_input = reward_input
        self.loss_kind = loss
        # Regression keeps the paper's hard clip for the policy (its loss uses the raw output, so no
        # gradient dies at the bound); the supremum loss needs a bound inside the loss, so it uses the
        # smooth tanh bound, and the policy sees that same bounded reward.
        self.bound: Bound = "clip" if loss == "regression" else "tanh"
        self.net = RewardNet(config.hidden_sizes, None if columns is None else tuple(columns), config.spectral_norm)
        self.tx = optax.chain(optax.add_decayed_weights(config.weight_decay), optax.adam(config.lr))
        self._update = jax.jit(self._update_many, donate_argnums=(0,))
        self._eval = jax.jit(self._loss_value)
        self._mean_reward = jax.jit(self._weighted_mean_reward)

    def init(self, key: jax.Array) -> RewardState:
        params = self.net.init(key, jnp.zeros((1, self.feature_dim), jnp.float32))
        return RewardState(params=params, opt_state=self.tx.init(params))

    def reward(self, params: Any, features: jax.Array) -> jax.Array:
        """Bounded rewards ``(B,)`` for reward inputs ``(B, d)``."""
        return bound_reward(self.net.apply(params, features), self.config.r_max, self.bound)

    def reward_fn(self, params: Any, batch: Batch) -> jax.Array:
        """The reward function handed to SAC: relabels a batch ``(B,)`` with the current reward."""
        return self.reward(params, batch_features(batch, self.reward_input))

    def _weighted_mean_reward(self, params: Any, features: jax.Array, weights: jax.Array) -> jax.Array:
        return jnp.sum(self.reward(params, features) * weights) / jnp.sum(weights)

    def mean_reward(self, params: Any, features: np.ndarray) -> float:
        """Mean bounded reward ``()`` over inputs ``(N, d)``, N > 0 (jitted; padded to few shapes)."""
        (padded,), weights = _pad_to_power_of_two([features])
        return float(self._mean_reward(params, padded, weights))

    def _loss(
        self, params: Any, inputs: jax.Array, targets: jax.Array, is_expert: jax.Array, weights: jax.Array
    ) -> tuple[jax.Array, Metrics]:
        """The ranking loss ``()`` and its metrics on inputs ``(B, d)`` with per-row ``(B,)`` arrays."""
        raw = self.net.apply(params, inputs)
        if self.loss_kind == "regression":
            return regression_ranking_loss(raw, targets, weights)
        return supremum_loss(bound_reward(raw, self.config.r_max, self.bound), is_expert, weights)

    def _loss_value(
        self, params: Any, inputs: jax.Array, targets: jax.Array, is_expert: jax.Array, weights: jax.Array
    ) -> jax.Array:
        return self._loss(params, inputs, targets, is_expert, weights)[0]

    def _training_loss(
        self,
        params: Any,
        inputs: jax.Array,
        targets: jax.Array,
        is_expert: jax.Array,
        offline: tuple[jax.Array, ...] | None,
    ) -> tuple[jax.Array, Metrics]:
        """The ranking loss of one batch; with offline batches, Eq. 6:
        ``(1 - w) L(agent vs expert) + w (L_states(offline) + L_snippets(offline)) / 2``.

        ``offline`` holds states ``(B, d)``, their targets ``(B,)``, snippets ``(S, l, d)`` and their
        targets ``(S,)`` (see :meth:`OfflineRankings.sample`).
        """
        online = self._loss(params, inputs, targets, is_expert, jnp.ones_like(targets))
        if offline is None:
            return online
        states, state_targets, snippets, snippet_targets = offline
        state_loss, _ = regression_ranking_loss(self.net.apply(params, states), state_targets)
        snippet_loss, _ = snippet_regression_loss(self.net.apply(params, snippets), snippet_targets)
        offline_loss = 0.5 * (state_loss + snippet_loss)
        weight = self.config.pref_weight
        return weighted_sum([(1.0 - weight, online), (weight, (offline_loss, {}))])

    def _update_many(
        self,
        state: RewardState,
        inputs: jax.Array,
        targets: jax.Array,
        is_expert: jax.Array,
        offline: tuple[jax.Array, ...] | None,
    ) -> tuple[RewardState, jax.Array]:
        """Gradient steps over batches ``inputs (n, B, d)``, ``targets (n, B)``, ``is_expert (n, B)``
        and, for the (pref) methods, ``n`` offline batches (else None)."""

        def step(carry: RewardState, batch: tuple[Any, ...]) -> tuple[RewardState, jax.Array]:
            x, y, e, off = batch
            (loss, _), grads = jax.value_and_grad(self._training_loss, has_aux=True)(carry.params, x, y, e, off)
            updates, opt_state = self.tx.update(grads, carry.opt_state, carry.params)
            return RewardState(optax.apply_updates(carry.params, updates), opt_state), loss

        state, losses = jax.lax.scan(step, state, (inputs, targets, is_expert, offline))
        return state, jnp.mean(losses)

    def fit_steps(
        self, state: RewardState, data: RankingData, n_updates: int, rng: np.random.Generator
    ) -> tuple[RewardState, float]:
        """About ``n_updates`` gradient steps (rounded up to whole chunks); returns the mean training loss."""
        losses = []
        chunk, batch_size = self.config.chunk, self.config.batch_size
        for _ in range(max(1, math.ceil(n_updates / chunk))):
            inputs, targets, is_expert = data.sample(rng, chunk, batch_size)
            offline = None if self.offline is None else self.offline.sample(rng, chunk, batch_size)
            state, loss = self._update(state, inputs, targets, is_expert, offline)
            losses.append(loss)
        return state, float(np.mean(jax.device_get(losses)))

    def _holdout_batch(self, data: RankingData) -> tuple[jax.Array, ...] | None:
        """Holdout inputs, targets, is-expert flags and weights, padded to a power of two (few shapes)."""
        inputs, targets, is_expert = data.holdout(HOLDOUT_MAX_ROWS)
        if len(inputs) == 0:
            return None
        (inputs, targets, is_expert), weights = _pad_to_power_of_two([inputs, targets, is_expert])
        return tuple(jnp.asarray(x) for x in (inputs, targets, is_expert, weights))

    def holdout_loss(self, params: Any, data: RankingData) -> float:
        """Loss on (at most ``HOLDOUT_MAX_ROWS`` rows of) the holdout; NaN when there is no holdout."""
        batch = self._holdout_batch(data)
        return float("nan") if batch is None else float(self._eval(params, *batch))

    def fit_until_converged(
        self, state: RewardState, data: RankingData, rng: np.random.Generator
    ) -> tuple[RewardState, dict[str, float]]:
        """Fit epoch by epoch until the holdout loss stops improving; keep the best parameters.

        One epoch is as many gradient steps as ``budget_rows`` training rows have mixtures, at one
        mixture per sampled row. By default (``real``) that is ``max(real agent states, H)`` rows: the
        absorbing padding is not counted, as all its rows are the same state, and an early phase of many
        short episodes would otherwise make epochs (and the time between convergence checks) dozens of
        times longer. ``all`` counts every row, the authors' epoch.
        """
        cfg = self.config
        rows = len(data.train_rows)
        if cfg.budget_rows == "real":
            rows = min(rows, max(data.n_real_states, data.horizon))
        per_epoch = max(1, math.ceil(rows * len(data.lambdas) / cfg.batch_size))
        holdout = self._holdout_batch(data)
        if holdout is None:  # no holdout: a single epoch
            state, train_loss = self.fit_steps(state, data, per_epoch, rng)
            return state, {"reward/train_loss": train_loss, "reward/holdout_loss": float("nan"), "reward/epochs": 1.0}
        best_loss = float(self._eval(state.params, *holdout))
        best_params = jax.tree.map(jnp.copy, state.params)  # the update donates state's buffers
        stale, epochs, train_loss = 0, 0, float("nan")
        while epochs < cfg.max_epochs and stale < cfg.patience:
            state, train_loss = self.fit_steps(state, data, per_epoch, rng)
            epochs += 1
            loss = float(self._eval(state.params, *holdout))
            if loss < best_loss:
                # Relative to |best|: the supremum loss is negative once the reward separates the data.
                improved = best_loss - loss > cfg.min_improvement * abs(best_loss)
                best_loss, best_params = loss, jax.tree.map(jnp.copy, state.params)
                stale = 0 if improved else stale + 1
            else:
                stale += 1
        state = RewardState(params=best_params, opt_state=state.opt_state)
        return state, {
            "reward/train_loss": train_loss,
            "reward/holdout_loss": best_loss,
            "reward/epochs": float(epochs),
        }


def _pad_to_power_of_two(arrays: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray]:
    """Zero-pad arrays of equal leading size N > 0 to the next power of two, so that jitted functions
    see few distinct shapes; returns the padded arrays and weights ``(N_padded,)`` (1 real, 0 padding)."""
    n = len(arrays[0])
    pad = (1 << (n - 1).bit_length()) - n
    padded = [np.concatenate([a, np.zeros((pad, *a.shape[1:]), a.dtype)]) for a in arrays]
    weights = np.concatenate([np.ones(n, np.float32), np.zeros(pad, np.float32)])
    return padded, weights
