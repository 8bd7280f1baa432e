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
    regression_ranking_loss,
    snippet_regression_loss,
    weighted_sum,
)
from rankgame.reward.offline_rankings import OfflineRankings
from rankgame.reward.ranking_data import RankingData
from rankgame.reward.targets import Schedule, lambda_grid, target_schedule

RankingSource = Literal["vanilla", "auto", "pref"]
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
                (self.pref_noise == 0.0 or source == "pref", "rankings pref_noise is used only by pref rankings"),
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
    """

    data: RankingData
    offline: OfflineRankings | None = None
    offline_weight: float = 0.0

    def sample(self, rng: np.random.Generator, n_batches: int, batch_size: int) -> tuple[Any, ...]:
        """``n_batches`` training batches: inputs ``(n, B, d)``, targets ``(n, B)``, is-expert flags
        ``(n, B)`` and, with offline rankings, their states, targets, snippets and snippet targets
        (:meth:`OfflineRankings.sample`), else None."""
        inputs, targets, is_expert = self.data.sample(rng, n_batches, batch_size)
        offline = None if self.offline is None else self.offline.sample(rng, n_batches, batch_size)
        return inputs, targets, is_expert, offline

    def objective(self, raw_fn: RawRewardFn, loss: RankingLoss, r_max: float) -> Objective:
        """The loss of one batch: ``loss`` on the agent-vs-expert chain and, with offline rankings, Eq. 6."""
        weight = self.offline_weight

        def objective(params: Any, batch: tuple[Any, ...]) -> tuple[jax.Array, Metrics]:
            inputs, targets, is_expert, offline = batch
            online = loss(raw_fn(params, inputs), targets, is_expert, jnp.ones_like(targets), r_max)
            if offline is None:
                return online
            states, state_targets, snippets, snippet_targets = offline
            state_loss, _ = regression_ranking_loss(raw_fn(params, states), state_targets)
            snippet_loss, _ = snippet_regression_loss(raw_fn(params, snippets), snippet_targets)
            return weighted_sum([(1.0 - weight, online), (weight, (0.5 * (state_loss + snippet_loss), {}))])

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
) -> Rankings:
    """The rankings of ``source``.

    Args:
        source: vanilla, auto or pref.
        config: targets and the offline chain's settings.
        expert: ``(M, H, d)`` expert reward inputs.
        layout: the reward inputs' layout (to count real agent states).
        holdout_fraction: share of agent rows the ranking data holds out of training.
        loss: the ranking loss; pref rankings need one that regresses targets.
        preferences: ``(p, H, d)`` reward inputs of the preference file's trajectories, worst first
            (pref only).
        mixup: how the auto mixtures pair agent and expert states: ``trajectory`` (time-aligned, the
            paper's) or ``state`` (an expert state from a random time step, App. D's regularizer ablation).
        noise_seed: seed of the preference noise (pref only).
    Raises:
        ValueError: a one-line reason for a combination that makes no sense.
    """
    config.validate(source)
    if mixup != "trajectory" and source != "auto":
        raise ValueError(f"state mixup is a variant of the auto rankings, not of {source}")
    if (preferences is not None) != (source == "pref"):
        raise ValueError("pref rankings need preference data, and only they use it")
    lambdas = lambda_grid(config.interpolations) if source == "auto" else np.array([0.0, 1.0])
    data = RankingData(
        expert, lambdas, config.targets(lambdas), holdout_fraction, layout, time_aligned=mixup == "trajectory"
    )
    if preferences is None:
        return Rankings(data)
    if not loss.regresses_targets:
        raise ValueError("offline rankings need a loss that regresses targets")
    positions = np.arange(len(preferences) + 1) / len(preferences)
    offline = OfflineRankings(
        preferences, expert, config.targets(positions), config.snippet_length, config.pref_noise, noise_seed
    )
    return Rankings(data, offline, config.pref_weight)
