"""The rankings choice of a method (Sec. 4.1-4.2, App. B.1): which behaviors the reward ranks, and how.

* ``vanilla``: the agent below the expert, ``rho^pi <= rho^E``: agent inputs regressed to 0, expert
  inputs to ``k`` (L_k, Eq. 2).
* ``auto``: the same chain with the automatically generated rankings between them, the time-aligned
  mixtures ``a[t] + lambda (e[t] - a[t])`` at ``lambda`` on :func:`~rankgame.reward.targets.lambda_grid`,
  each regressed to its scheduled target ``k(lambda)`` (SL_k, Eq. 8).
* ``pref``: the agent-vs-expert chain plus a fixed chain of offline trajectories ranked below the
  expert (a preference file), fit together as Eq. 6:
  ``(1 - w) L(agent vs expert) + w (L_states(offline) + L_snippets(offline)) / 2`` with ``w`` the
  offline weight (Table 4: 0.3). Offline trajectory ``i`` of ``p`` (worst first) is regressed to the
  schedule's target at ``i / p`` of the way from the agent's target to the expert's.
* ``offline``: only the offline chain of a preference file, grounded by the expert on top, compared
  in pairs of snippets (T-REX, Brown et al. 2019); the agent's own data is never ranked, so the
  reward is learned before the policy moves (the ``reward-first`` leader). Needs a pairwise loss.

Every source can also give the points of a gradient penalty (losses that have one): random
interpolations between agent and expert inputs (:meth:`RankingData.sample_interpolates`).

:func:`build_rankings` turns expert (and preference) reward inputs into a :class:`Rankings`, which
owns the ranking data the leader adds agent trajectories to, samples training batches and defines
the objective the reward player minimizes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np

from rankgame.errors import nonfinite_fields, require
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import (
    Metrics,
    RankingLoss,
    gradient_penalty,
    regression_ranking_loss,
    snippet_regression_loss,
    weighted_sum,
)
from rankgame.reward.offline_rankings import OfflineRankings
from rankgame.reward.ranking_data import RankingData
from rankgame.reward.targets import Schedule, lambda_grid, target_schedule

RankingSource = Literal["vanilla", "auto", "pref", "offline"]
Mixup = Literal["trajectory", "state"]

#: Regression target of agent inputs, the bottom of every chain (the paper's 0).
AGENT_TARGET = 0.0


@dataclass(frozen=True)
class RankingsConfig:
    """Which behaviors are ranked and the regression targets they get (Table 4)."""

    k: float = 10.0
    """Performance gap k: expert inputs are regressed to k, agent inputs to 0."""
    schedule: Schedule = "exp"
    """Targets of the auto mixtures and of the offline chain: linear or exp."""
    beta: float = -1.0
    """Temperature of the exp schedule (Table 4: -1; the authors' Ant configuration uses -2)."""
    interpolations: int = 4
    """Interior mixtures between agent and expert (auto rankings): 4 gives lambda = 0, 0.2, ..., 1, the
    grid of the authors' code (Table 4's "5 interpolations" counts its five steps)."""
    pref_weight: float = 0.3
    """Weight of the offline rankings' loss, 1 - alpha in Eq. 6 (Table 4: 0.3); the agent-vs-expert
    ranking gets the rest (pref rankings)."""
    pref_noise: float = 0.0
    """Share of the offline rankings' state and snippet labels replaced, once per run, by the rank of
    another offline trajectory (noisy preferences; pref rankings)."""
    snippet_length: int = 10
    """Steps per snippet of an offline trajectory whose summed reward is regressed to k_i l (pref)."""

    def validate(self, source: RankingSource) -> None:
        """Raise ``ValueError`` with a one-line reason for settings that make no sense for ``source``."""
        require(
            [
                (not nonfinite_fields(self), f"rankings {', '.join(nonfinite_fields(self))} must be finite"),
                (self.k > 0, "rankings k must be positive"),
                (self.interpolations >= 0, "rankings interpolations must be >= 0"),
                (0.0 <= self.pref_weight <= 1.0, "rankings pref_weight must lie in [0, 1]"),
                (0.0 <= self.pref_noise <= 1.0, f"rankings pref_noise must lie in [0, 1] (got {self.pref_noise})"),
                (self.snippet_length > 0, "rankings snippet_length must be positive"),
                (
                    self.pref_noise == 0.0 or source in ("pref", "offline"),
                    "rankings pref_noise is used only by the pref and offline rankings",
                ),
            ]
        )

    def targets(self, positions: np.ndarray) -> np.ndarray:
        """Scheduled targets ``(n,)`` at ``positions (n,)`` in ``[0, 1]`` of the way from agent to expert."""
        return target_schedule(positions, AGENT_TARGET, AGENT_TARGET + self.k, self.schedule, self.beta)


#: ``(params, inputs (..., d)) -> raw rewards (...)``.
RawRewardFn = Callable[[Any, jax.Array], jax.Array]
#: ``(params, batch) -> (loss (), metrics)``, with the batch of :meth:`Rankings.sample`.
Objective = Callable[[Any, tuple[Any, ...]], tuple[jax.Array, Metrics]]


@dataclass
class Rankings:
    """What the reward player fits.

    Attributes:
        data: agent trajectories ranked below the expert (with the auto mixtures in between); the
            leader adds agent data to it.
        offline: the pref rankings' fixed chain of offline trajectories, else None.
        offline_weight: ``w`` of Eq. 6 (ignored without ``offline``).
        penalty_points: also sample the points of a gradient penalty (a loss that has one).
    """

    data: RankingData
    offline: OfflineRankings | None = None
    offline_weight: float = 0.0
    penalty_points: bool = False

    def sample(self, rng: np.random.Generator, n_batches: int, batch_size: int) -> tuple[Any, ...]:
        """``n_batches`` training batches: inputs ``(n, B, d)``, targets ``(n, B)``, is-expert flags
        ``(n, B)``; with offline rankings, their states, targets, snippets and snippet targets
        (:meth:`OfflineRankings.sample`), else None; with ``penalty_points``, interpolated inputs
        ``(n, B, d)``, else None."""
        inputs, targets, is_expert = self.data.sample(rng, n_batches, batch_size)
        offline = None if self.offline is None else self.offline.sample(rng, n_batches, batch_size)
        points = self.data.sample_interpolates(rng, n_batches, batch_size) if self.penalty_points else None
        return inputs, targets, is_expert, offline, points

    def objective(self, raw_fn: RawRewardFn, loss: RankingLoss, r_max: float, penalty: float = 0.0) -> Objective:
        """The loss of one batch: ``loss`` on the agent-vs-expert chain, with offline rankings Eq. 6, and
        with ``penalty_points`` plus ``penalty`` times the gradient penalty."""
        weight = self.offline_weight

        def objective(params: Any, batch: tuple[Any, ...]) -> tuple[jax.Array, Metrics]:
            inputs, targets, is_expert, offline, points = batch
            result = loss(raw_fn(params, inputs), targets, is_expert, jnp.ones_like(targets), r_max)
            if offline is not None:
                states, state_targets, snippets, snippet_targets = offline
                state_loss, _ = regression_ranking_loss(raw_fn(params, states), state_targets)
                snippet_loss, _ = snippet_regression_loss(raw_fn(params, snippets), snippet_targets)
                result = weighted_sum([(1.0 - weight, result), (weight, (0.5 * (state_loss + snippet_loss), {}))])
            if points is not None:
                value = gradient_penalty(lambda x: raw_fn(params, x), points)
                result = (result[0] + penalty * value, {**result[1], "gradient_penalty": value})
            return result

        return objective


@dataclass
class PairwiseRankings:
    """The ``offline`` rankings: pairs of snippets of a fixed ranked chain, for a pairwise loss (T-REX).

    Attributes:
        data: agent-vs-expert data that the reward never fits (it keeps the expert inputs the game
            reports rewards of); no leader that adds agent data may be paired with these rankings.
        offline: the chain of offline trajectories and the expert.
        snippet_length: ``l``; each batch of ``B`` inputs holds ``max(1, B // (2 l))`` pairs.
    """

    data: RankingData
    offline: OfflineRankings
    snippet_length: int

    def sample(self, rng: np.random.Generator, n_batches: int, batch_size: int) -> tuple[Any, ...]:
        """Better and worse snippets ``(n, S, l, d)`` each (:meth:`OfflineRankings.sample_pairs`)."""
        return self.offline.sample_pairs(rng, n_batches, max(1, batch_size // (2 * self.snippet_length)))

    def objective(self, raw_fn: RawRewardFn, loss: RankingLoss, r_max: float, penalty: float = 0.0) -> Objective:
        """``loss`` on the summed raw rewards ``(S,)`` of the better and the worse snippets."""

        def objective(params: Any, batch: tuple[Any, ...]) -> tuple[jax.Array, Metrics]:
            better, worse = batch
            return loss.fn(jnp.sum(raw_fn(params, better), -1), jnp.sum(raw_fn(params, worse), -1))  # type: ignore[call-arg]

        return objective


def build_rankings(
    source: RankingSource,
    config: RankingsConfig,
    expert: np.ndarray,
    layout: InputLayout,
    holdout_fraction: float,
    loss: RankingLoss,
    preferences: np.ndarray | None = None,
    mixup: Mixup = "trajectory",
    noise_seed: int | Sequence[int] = 0,
) -> Rankings | PairwiseRankings:
    """The rankings of ``source``.

    Args:
        source: vanilla, auto or pref.
        config: targets and the offline chain's settings.
        expert: ``(M, H, d)`` expert reward inputs.
        layout: the reward inputs' layout (to count real agent states).
        holdout_fraction: share of agent rows the ranking data holds out of training.
        loss: the ranking loss; pref rankings need one that regresses targets, offline rankings a
            pairwise one, and only they use one.
        preferences: ``(p, H, d)`` reward inputs of the preference file's trajectories, worst first
            (pref and offline only).
        mixup: how the auto mixtures pair agent and expert states: ``trajectory`` (time-aligned, the
            paper's) or ``state`` (an expert state from a random time step, App. D's regularizer ablation).
        noise_seed: seed of the preference noise (pref only).
    Raises:
        ValueError: a one-line reason for a combination that makes no sense.
    """
    config.validate(source)
    if mixup != "trajectory" and source != "auto":
        raise ValueError(f"state mixup is a variant of the auto rankings, not of {source}")
    if (preferences is not None) != (source in ("pref", "offline")):
        raise ValueError(f"{source} rankings {'need' if preferences is None else 'use no'} preference data")
    if loss.pairwise != (source == "offline"):
        raise ValueError("offline rankings need a pairwise loss, and only they use one")
    lambdas = lambda_grid(config.interpolations) if source == "auto" else np.array([0.0, 1.0])
    data = RankingData(
        expert, lambdas, config.targets(lambdas), holdout_fraction, layout, time_aligned=mixup == "trajectory"
    )
    if preferences is None:
        return Rankings(data, penalty_points=loss.gradient_penalty)
    if source == "pref" and not loss.regresses_targets:
        raise ValueError("pref rankings need a loss that regresses targets")
    positions = np.arange(len(preferences) + 1) / len(preferences)
    offline = OfflineRankings(
        preferences, expert, config.targets(positions), config.snippet_length, config.pref_noise, noise_seed
    )
    if source == "offline":
        return PairwiseRankings(data, offline, config.snippet_length)
    return Rankings(data, offline, config.pref_weight, penalty_points=loss.gradient_penalty)
