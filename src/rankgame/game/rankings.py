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
* ``marginal``: f-IRL's comparison of the expert's and the agent's state marginals through an
  estimated density ratio (:class:`MarginalRankings`). Needs a marginal loss.

The regression sources (vanilla, auto, pref) can also rank *standing still* at the agent's level, with
the same mixtures toward the expert as agent data, fit with a share ``still_weight`` of the
agent-vs-expert loss: ``(1 - w_s) L(agent vs expert) + w_s L(standing still vs expert)``. This is not in
the paper. PAL ranks only the current agent data below the expert, so once the agent moves, no ranking
holds a standing state and its reward is free to rise to the expert's; the standing-still ranking keeps
it at the bottom for the whole run. ``still_poses`` says which poses stand still:

* ``initial``: the expert's initial states held for the whole horizon
  (:meth:`~rankgame.reward.inputs.InputLayout.standing_still`);
* ``expert``: every expert state ``e[t]`` held for one step, the self-transition ``(e[t], e[t])`` of an
  ``(s, s')`` reward (:meth:`~rankgame.reward.inputs.InputLayout.held_still`). Its time-aligned mixture
  with the expert's own transition is ``(e[t], e[t] + lambda (e[t+1] - e[t]))``: the reward is taught to
  grow with the share of the expert's step taken, from any of the expert's poses.

Every source can also give the points of a gradient penalty (losses that have one): random
interpolations between agent and expert inputs (:meth:`RankingData.sample_interpolates`).

:func:`build_rankings` turns expert (and preference) reward inputs into a :class:`Rankings`, which
owns the ranking data the leader adds agent trajectories to, samples training batches and defines
the objective the reward player minimizes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np

from rankgame.checkpoint import flatten_tree, unflatten_tree
from rankgame.errors import nonfinite_fields, require
from rankgame.reward.density_ratio import DensityRatio
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import (
    H_FUNCTIONS,
    Divergence,
    Metrics,
    RankingLoss,
    bound_reward,
    gradient_penalty,
    regression_ranking_loss,
    snippet_regression_loss,
    weighted_sum,
)
from rankgame.reward.offline_rankings import OfflineRankings
from rankgame.reward.ranking_data import RankingData
from rankgame.reward.targets import Schedule, lambda_grid, target_schedule

RankingSource = Literal["vanilla", "auto", "pref", "offline", "marginal"]
Mixup = Literal["trajectory", "state"]
StillPoses = Literal["initial", "expert"]

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
    divergence: Divergence = "fkl"
    """f-divergence between the state marginals whose gradient the reward follows: forward KL, reverse
    KL or Jensen-Shannon (marginal rankings: f-irl)."""
    ratio_steps: int = 1200
    """Density-ratio classifier steps before each reward turn (marginal rankings: f-irl)."""
    still_weight: float = 0.0
    """Share of the agent-vs-expert loss given to ranking standing still at the agent's level; 0 turns it
    off, the paper's method (vanilla, auto, pref)."""
    still_poses: StillPoses = "initial"
    """Which poses are ranked standing still (with ``still_weight``): ``initial``, the expert's initial
    states held for the horizon; ``expert``, every expert state held for one step, the self-transition
    ``(s, s)`` ranked below the expert's ``(s, s')`` (an ``(s, s')`` reward only)."""

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
                (self.ratio_steps > 0, "rankings ratio_steps must be positive"),
                (0.0 <= self.still_weight < 1.0, f"rankings still_weight must lie in [0, 1) (got {self.still_weight})"),
                (
                    self.still_weight == 0.0 or source in ("vanilla", "auto", "pref"),
                    "rankings still_weight is used only by the vanilla, auto and pref rankings",
                ),
                (
                    self.still_poses == "initial" or self.still_weight > 0.0,
                    "rankings still_poses needs still_weight > 0",
                ),
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


class _StoredInData:
    """Rankings built on one ranking dataset ``self.data``; unless a source says otherwise, that data is
    their only changing state and nothing is re-estimated before a reward turn."""

    data: RankingData

    def refresh(self, rng: np.random.Generator) -> dict[str, float]:
        """Nothing to re-estimate before a reward turn (see :meth:`MarginalRankings.refresh`)."""
        return {}

    def state_dict(self) -> dict[str, np.ndarray]:
        """Arrays that restore the rankings' changing state (the agent data)."""
        return self.data.state_dict()

    def load_state_dict(self, arrays: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`state_dict`."""
        self.data.load_state_dict(arrays)

    def replace_expert(self, expert: np.ndarray, rng: np.random.Generator) -> None:
        """Rank below other expert inputs ``(M', H, d)`` from now on (a changed intent)."""
        self.data.replace_expert(expert, rng)


@dataclass
class Rankings(_StoredInData):
    """What the reward player fits.

    Attributes:
        data: agent trajectories ranked below the expert (with the auto mixtures in between); the
            leader adds agent data to it.
        offline: the pref rankings' fixed chain of offline trajectories, else None.
        offline_weight: ``w`` of Eq. 6 (ignored without ``offline``).
        penalty_points: also sample the points of a gradient penalty (a loss that has one).
        still_weight: ``w_s``, the share of the agent-vs-expert loss that ``still`` gets.
        still_of: builds the standing-still rankings from expert inputs ``(M, H, d)`` (its poses come
            from the expert, so a changed expert gets its own); None to rank no standing still.
        still: standing still ranked below the expert, with the same mixtures (its agent data is fixed),
            built by ``still_of`` from ``data``'s expert; None without ``still_of``.
    """

    data: RankingData
    offline: OfflineRankings | None = None
    offline_weight: float = 0.0
    penalty_points: bool = False
    still_weight: float = 0.0
    still_of: Callable[[np.ndarray], RankingData] | None = None
    still: RankingData | None = field(init=False)

    def __post_init__(self) -> None:
        self.still = None if self.still_of is None else self.still_of(self.data.expert)

    def sample(self, rng: np.random.Generator, n_batches: int, batch_size: int) -> tuple[Any, ...]:
        """``n_batches`` training batches: inputs ``(n, B, d)``, targets ``(n, B)``, is-expert flags
        ``(n, B)``; with offline rankings, their states, targets, snippets and snippet targets
        (:meth:`OfflineRankings.sample`), else None; with ``penalty_points``, interpolated inputs
        ``(n, B, d)``, else None; with ``still``, its inputs, targets and is-expert flags, else None."""
        inputs, targets, is_expert = self.data.sample(rng, n_batches, batch_size)
        offline = None if self.offline is None else self.offline.sample(rng, n_batches, batch_size)
        points = self.data.sample_interpolates(rng, n_batches, batch_size) if self.penalty_points else None
        still = None if self.still is None else self.still.sample(rng, n_batches, batch_size)
        return inputs, targets, is_expert, offline, points, still

    def replace_expert(self, expert: np.ndarray, rng: np.random.Generator) -> None:
        """Rank below other expert inputs ``(M', H, d)`` from now on (a changed intent); standing still is
        rebuilt from the new expert's poses."""
        self.data.replace_expert(expert, rng)
        if self.still_of is not None:
            self.still = self.still_of(expert)

    def objective(self, raw_fn: RawRewardFn, loss: RankingLoss, r_max: float, penalty: float = 0.0) -> Objective:
        """The loss of one batch: ``loss`` on the agent-vs-expert chain (with ``still``, a share
        ``still_weight`` of it on standing still against the expert), with offline rankings Eq. 6, and
        with ``penalty_points`` plus ``penalty`` times the gradient penalty."""
        weight, still_weight = self.offline_weight, self.still_weight

        def objective(params: Any, batch: tuple[Any, ...]) -> tuple[jax.Array, Metrics]:
            inputs, targets, is_expert, offline, points, still = batch

            def chain_loss(x: jax.Array, t: jax.Array, e: jax.Array) -> tuple[jax.Array, Metrics]:
                return loss(raw_fn(params, x), t, e, jnp.ones_like(t), r_max)

            result = chain_loss(inputs, targets, is_expert)
            if still is not None:
                still_loss, _ = chain_loss(*still)
                result = ((1.0 - still_weight) * result[0] + still_weight * still_loss, result[1])
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
class PairwiseRankings(_StoredInData):
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


@dataclass
class MarginalRankings(_StoredInData):
    """The ``marginal`` rankings of f-IRL (Ni et al. 2020): the expert's state marginal against the
    agent's, compared through an estimated density ratio.

    Before each reward turn (:meth:`refresh`) the classifier of :class:`~rankgame.reward.density_ratio.
    DensityRatio` is fit for ``ratio_steps`` steps on every expert input against every agent input of the
    iteration (padding included: an absorbing state is one the expert never visits), and each trajectory
    gets its summed ``h_f`` of the estimated log ratio. A batch holds every agent trajectory of the
    iteration and ``expert_trajectories`` expert trajectories drawn with replacement, as the f-IRL
    authors' covariance sample does; the objective is :func:`~rankgame.reward.losses.f_divergence_surrogate`.

    Attributes:
        data: the iteration's agent trajectories and the expert's (no holdout).
        ratio: the density-ratio classifier.
        divergence: which ``h_f`` (:data:`~rankgame.reward.losses.H_FUNCTIONS`).
        ratio_steps: classifier steps per reward turn.
        expert_trajectories: expert trajectories in each batch.
        seed: seeds the classifier's parameters.
    """

    data: RankingData
    ratio: DensityRatio
    divergence: Divergence
    ratio_steps: int
    expert_trajectories: int = 10
    seed: int = 0

    def __post_init__(self) -> None:
        self.ratio_state = self.ratio.init(jax.random.key(self.seed))
        self.ratio_loss = float("nan")
        """The classifier's mean loss in its last fit."""
        self._h_agent = np.zeros(0, np.float32)
        self._h_expert = np.zeros(0, np.float32)

    def refresh(self, rng: np.random.Generator) -> dict[str, float]:
        """Fit the classifier on the current data and sum ``h_f`` of its log ratio along every trajectory;
        ``{"reward/ratio_loss": the classifier's mean loss}``."""
        expert, agent = self.data.expert, self.data.agent
        if len(agent) == 0:
            raise ValueError("the marginal rankings have no agent trajectory to compare with the expert")
        dim = expert.shape[-1]
        self.ratio_state, self.ratio_loss = self.ratio.fit(
            self.ratio_state, expert.reshape(-1, dim), agent.reshape(-1, dim), rng, self.ratio_steps
        )
        h = H_FUNCTIONS[self.divergence]
        self._h_agent = np.asarray(jnp.sum(h(self.ratio.log_ratio(self.ratio_state.params, agent)), axis=-1))
        self._h_expert = np.asarray(jnp.sum(h(self.ratio.log_ratio(self.ratio_state.params, expert)), axis=-1))
        return {"reward/ratio_loss": self.ratio_loss}

    def sample(self, rng: np.random.Generator, n_batches: int, batch_size: int) -> tuple[Any, ...]:
        """``n_batches`` copies of the agent trajectories with fresh draws of expert trajectories: inputs
        ``(n, N, H, d)``, summed ``h_f`` ``(n, N)`` and weights ``(n, N)`` (0 on padding to a power of two)."""
        if len(self._h_agent) != len(self.data.agent):
            raise ValueError("the marginal rankings were not refreshed since agent data was added")
        draws = rng.integers(0, len(self.data.expert), size=(n_batches, self.expert_trajectories))
        n_agent = len(self.data.agent)
        size = 1 << (n_agent + self.expert_trajectories - 1).bit_length()
        horizon, dim = self.data.horizon, self.data.dim
        inputs = np.zeros((n_batches, size, horizon, dim), np.float32)
        h_sums = np.zeros((n_batches, size), np.float32)
        weights = np.zeros((n_batches, size), np.float32)
        inputs[:, :n_agent] = self.data.agent
        h_sums[:, :n_agent] = self._h_agent
        end = n_agent + self.expert_trajectories
        inputs[:, n_agent:end] = self.data.expert[draws]
        h_sums[:, n_agent:end] = self._h_expert[draws]
        weights[:, :end] = 1.0
        return inputs, h_sums, weights

    def objective(self, raw_fn: RawRewardFn, loss: RankingLoss, r_max: float, penalty: float = 0.0) -> Objective:
        """``loss`` on the trajectories' summed bounded rewards ``(N,)`` and summed ``h_f``. The covariance
        is unbounded below in the rewards, so it acts on the reward the policy sees (clipped to
        ``[-r_max, r_max]``, as the f-IRL authors clamp theirs), whose gradient stops at the bound."""
        horizon = self.data.horizon

        def objective(params: Any, batch: tuple[Any, ...]) -> tuple[jax.Array, Metrics]:
            inputs, h_sums, weights = batch
            rewards = bound_reward(raw_fn(params, inputs), r_max, loss.bound)
            return loss.fn(jnp.sum(rewards, -1), h_sums, weights, horizon)  # type: ignore[call-arg]

        return objective

    def state_dict(self) -> dict[str, np.ndarray]:
        """The agent data and the classifier."""
        return {**self.data.state_dict(), **flatten_tree("ratio", self.ratio_state)}

    def load_state_dict(self, arrays: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`state_dict`."""
        self.data.load_state_dict(arrays)
        self.ratio_state = unflatten_tree("ratio", arrays, self.ratio_state)


def _still_rankings(
    poses: StillPoses,
    lambdas: np.ndarray,
    targets: np.ndarray,
    layout: InputLayout,
    time_aligned: bool,
    expert: np.ndarray,
) -> RankingData:
    """Standing still ranked below ``expert`` ``(M, H, d)`` with the mixtures ``lambdas (G,)`` and their
    ``targets (G,)``: the expert's initial poses held for the horizon, or (``expert``) every expert pose
    held still; absorbing padding is not ranked."""
    still = RankingData(expert, lambdas, targets, 0.0, layout, time_aligned=time_aligned)
    held = layout.standing_still(expert[:, 0], expert.shape[1]) if poses == "initial" else layout.held_still(expert)
    still.add(list(held), np.random.default_rng(0), real_only=True)
    return still


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
    ratio_seed: int = 0,
    penalty_points: bool | None = None,
) -> Rankings | PairwiseRankings | MarginalRankings:
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
        ratio_seed: seed of the density-ratio classifier's parameters (marginal only).
        penalty_points: sample the points of a gradient penalty (vanilla, auto and pref); default:
            whether ``loss`` has one.
    Raises:
        ValueError: a one-line reason for a combination that makes no sense.
    """
    config.validate(source)
    penalty = loss.gradient_penalty if penalty_points is None else penalty_points
    if mixup != "trajectory" and source != "auto":
        raise ValueError(f"state mixup is a variant of the auto rankings, not of {source}")
    if (preferences is not None) != (source in ("pref", "offline")):
        raise ValueError(f"{source} rankings {'need' if preferences is None else 'use no'} preference data")
    if loss.pairwise != (source == "offline"):
        raise ValueError("offline rankings need a pairwise loss, and only they use one")
    if loss.marginal != (source == "marginal"):
        raise ValueError("marginal rankings need a marginal loss, and only they use one")
    if source == "marginal":
        data = RankingData(expert, np.array([0.0, 1.0]), config.targets(np.array([0.0, 1.0])), 0.0, layout)
        ratio = DensityRatio(expert.shape[-1])
        return MarginalRankings(data, ratio, config.divergence, config.ratio_steps, seed=ratio_seed)
    lambdas = lambda_grid(config.interpolations) if source == "auto" else np.array([0.0, 1.0])
    time_aligned = mixup == "trajectory"
    data = RankingData(expert, lambdas, config.targets(lambdas), holdout_fraction, layout, time_aligned=time_aligned)
    still_of = None
    if config.still_weight > 0.0:
        if not loss.regresses_targets:
            raise ValueError("rankings still_weight needs a loss that regresses targets")
        if config.still_poses == "expert" and layout.kind != "ss":
            raise ValueError("rankings still_poses expert needs an (s, s') reward")
        still_of = partial(_still_rankings, config.still_poses, lambdas, config.targets(lambdas), layout, time_aligned)
    parts = {"still_weight": config.still_weight, "still_of": still_of}
    if preferences is None:
        return Rankings(data, penalty_points=penalty, **parts)
    if source == "pref" and not loss.regresses_targets:
        raise ValueError("pref rankings need a loss that regresses targets")
    positions = np.arange(len(preferences) + 1) / len(preferences)
    offline = OfflineRankings(
        preferences, expert, config.targets(positions), config.snippet_length, config.pref_noise, noise_seed
    )
    if source == "offline":
        return PairwiseRankings(data, offline, config.snippet_length)
    return Rankings(data, offline, config.pref_weight, penalty, **parts)
