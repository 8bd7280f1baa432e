"""The leader choice of a method (Sec. 4.3, App. B.2): which agent data the reward sees, and its whole budget.

The paper's two Stackelberg leaders:

* PAL (policy as leader): the reward sees only the current iteration's agent data and is fit *to
  convergence* on it (Alg. 2): epoch after epoch until the loss on a shuffled holdout of agent rows
  (``holdout_fraction``) has not improved by more than :data:`MIN_IMPROVEMENT` of itself for
  ``patience`` epochs, or ``max_epochs`` have passed; the best parameters are kept. One epoch is as
  many gradient steps as the training rows have mixtures, at one mixture per sampled row.
* RAL (reward as leader): the reward sees *all* agent data so far and takes
  ``n_rew = ral_passes |D| / batch_size`` gradient steps per iteration (Alg. 3, Table 4), rounded up to
  whole fused calls. It holds out the same share of agent rows, only to log a holdout loss. Each step
  draws one mixture per sampled row, so with the default grid one pass covers a sixth of the mixtures.

Both budgets count the real agent states, not the absorbing states that pad short episodes to the
horizon (``rows="real"``): padding would multiply the budget of an early phase full of short episodes
by up to H / (episode length). A PAL epoch counts at least H rows. App. D's ablations change a
leader's budget: :func:`make_leader` takes the other leader's budget (``budget``) or counts the
padding as the authors' code does (``rows="all"``).

The older methods' non-Stackelberg choices (the paper's table of methods, Sec. 3):

* ``gda`` (simultaneous gradient steps, GAIL / GAIfO): neither player converges before the other
  moves. The reward sees only the current iteration's agent data (an on-policy rollout) and takes a
  fixed ``gda_steps`` gradient steps on it; by default :data:`GDA_PASSES` passes over its agent rows
  (half of every sampled batch is agent inputs, half expert inputs).
* ``gda-replay`` (DAC / DACfO): the same, with all agent data so far (the replay buffer) ranked below
  the expert; by default ``n_pol / 10`` steps per iteration, which at the default batch of 1024 draws
  about as many discriminator samples per policy update as DAC's one batch of 100. f-IRL plays ``gda``
  with one reward step per iteration of five horizons (its method row sets both).
* ``reward-first`` (T-REX): the reward is fit once, for ``opening_steps`` gradient steps on the offline
  rankings, before the policy takes its first step, and then held fixed; it sees no agent data.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

from rankgame.errors import nonfinite_fields, require
from rankgame.game.rankings import Rankings
from rankgame.reward.player import RewardPlayer, RewardState

LeaderName = Literal["pal", "ral", "gda", "gda-replay", "reward-first"]
Budget = Literal["holdout", "passes", "fixed", "opening"]
BudgetRows = Literal["real", "all"]

#: A relative decrease of the holdout loss smaller than this is no improvement (holdout budget).
MIN_IMPROVEMENT = 0.01

#: Passes over the iteration's agent rows of the gda leader by default (the discriminator epochs per
#: rollout of the widely used PPO-GAIL implementation of Kostrikov, pytorch-a2c-ppo-acktr-gail).
GDA_PASSES = 5


@dataclass(frozen=True)
class LeaderConfig:
    """The reward's budget per iteration (Table 4)."""

    holdout_fraction: float = 0.1
    """Share of agent rows held out of training, at most 0.5: the holdout budget (PAL's) stops fitting
    when their loss stops improving; the passes budget (RAL's) only logs their loss."""
    patience: int = 3
    """Epochs without holdout improvement before fitting stops (holdout budget)."""
    max_epochs: int = 50
    """Upper bound on epochs per fit (holdout budget)."""
    ral_passes: float = 1.0
    """Passes over the agent data per iteration with the passes budget (RAL's): n_rew = ral_passes |D| /
    batch_size gradient steps, |D| the real agent states."""
    gda_steps: int | None = None
    """Reward gradient steps per iteration of the simultaneous leaders (gda, gda-replay); default: five
    passes over the iteration's agent rows (gda), n_pol / 10 (gda-replay)."""
    opening_steps: int = 2000
    """Gradient steps of the reward-first leader's one fit before the policy starts (T-REX)."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense."""
        require(
            [
                (not nonfinite_fields(self), f"leader {', '.join(nonfinite_fields(self))} must be finite"),
                (0.0 <= self.holdout_fraction <= 0.5, "leader.holdout_fraction must lie in [0, 0.5]"),
                (self.patience > 0 and self.max_epochs > 0, "leader.patience and leader.max_epochs must be positive"),
                (self.ral_passes > 0, "leader.ral_passes must be positive"),
                (self.gda_steps is None or self.gda_steps > 0, "leader.gda_steps must be positive"),
                (self.opening_steps > 0, "leader.opening_steps must be positive"),
            ]
        )


@dataclass(frozen=True)
class Leader:
    """What the reward sees of the agent data and how long it trains each turn.

    Attributes:
        keeps_history: aggregate all agent data (RAL, gda-replay) or keep only the current iteration's.
        budget: ``holdout`` (fit until the holdout loss stops improving), ``passes`` (``n_rew`` steps),
            ``fixed`` (``gda_steps``) or ``opening`` (one fit before the policy starts, none after).
        config: the budgets' settings.
        rows: which agent rows size the budgets: ``real`` states only, or ``all`` rows with the padding.
        policy_updates: policy updates per iteration, ``n_pol`` (sizes gda-replay's default budget).
        method_steps: the fixed budget's steps per iteration when the method sets them (f-IRL's one
            step, rounded up to a fused call) and ``gda_steps`` is not given.
    """

    keeps_history: bool
    budget: Budget
    config: LeaderConfig
    rows: BudgetRows = "real"
    policy_updates: int = 1000
    method_steps: int | None = None

    @property
    def moves_first(self) -> bool:
        """Whether the reward is fit once before the policy's first step and never after (T-REX)."""
        return self.budget == "opening"

    def opening(
        self, player: RewardPlayer, state: RewardState, rng: np.random.Generator
    ) -> tuple[RewardState, dict[str, float]]:
        """The reward-first leader's one fit, on rankings that hold no agent data."""
        state, train_loss, metrics = player.fit_steps(state, self.config.opening_steps, rng)
        return state, {
            **metrics,
            "reward/train_loss": train_loss,
            "reward/holdout_loss": float("nan"),
            "reward/epochs": float("nan"),
        }

    def receive(self, rankings: Rankings, trajectories: Sequence[np.ndarray], rng: np.random.Generator) -> None:
        """Add the agent trajectories ``(H, d)`` finished this iteration to the ranking data."""
        if self.moves_first:
            return
        if not self.keeps_history:
            rankings.data.clear()
        rankings.data.add(trajectories, rng)

    def fit(
        self, player: RewardPlayer, state: RewardState, rng: np.random.Generator
    ) -> tuple[RewardState, dict[str, float]] | None:
        """The reward player's turn; metrics ``reward/train_loss``, ``reward/holdout_loss``, ``reward/epochs``
        and the loss's own metrics. None for the reward-first leader, whose reward no longer moves."""
        if self.moves_first:
            return None
        refreshed = player.rankings.refresh(rng)
        if self.budget == "holdout":
            state, metrics = self._fit_until_converged(player, state, rng)
            return state, {**metrics, **refreshed}
        data = player.rankings.data
        rows = data.n_real_states if self.rows == "real" else len(data.train_rows)
        if self.budget == "passes":
            n_updates = max(1, math.ceil(self.config.ral_passes * rows / player.config.batch_size))
        elif self.config.gda_steps is not None:
            n_updates = self.config.gda_steps
        elif self.method_steps is not None:
            n_updates = self.method_steps
        elif self.keeps_history:
            n_updates = max(1, self.policy_updates // 10)
        else:  # half of each batch is agent inputs: 2 rows per pass
            n_updates = max(1, math.ceil(GDA_PASSES * 2 * rows / player.config.batch_size))
        state, train_loss, metrics = player.fit_steps(state, n_updates, rng)
        return state, {
            **metrics,
            **refreshed,
            "reward/train_loss": train_loss,
            "reward/holdout_loss": player.holdout_loss(state.params, player.holdout_batch(data)),
            "reward/epochs": float("nan"),
        }

    def _fit_until_converged(
        self, player: RewardPlayer, state: RewardState, rng: np.random.Generator
    ) -> tuple[RewardState, dict[str, float]]:
        cfg, data = self.config, player.rankings.data
        rows = len(data.train_rows)
        if self.rows == "real":
            rows = min(rows, max(data.n_real_states, data.horizon))
        per_epoch = max(1, math.ceil(rows * len(data.lambdas) / player.config.batch_size))
        holdout = player.holdout_batch(data)
        if holdout is None:  # no holdout: a single epoch
            state, train_loss, metrics = player.fit_steps(state, per_epoch, rng)
            return state, {
                **metrics,
                "reward/train_loss": train_loss,
                "reward/holdout_loss": float("nan"),
                "reward/epochs": 1.0,
            }
        best_loss = player.holdout_loss(state.params, holdout)
        best_params = jax.tree.map(jnp.copy, state.params)  # the update donates state's buffers
        stale, epochs, train_loss, metrics = 0, 0, float("nan"), {}
        while epochs < cfg.max_epochs and stale < cfg.patience:
            state, train_loss, metrics = player.fit_steps(state, per_epoch, rng)
            epochs += 1
            loss = player.holdout_loss(state.params, holdout)
            if loss < best_loss:
                # Relative to |best|: the supremum loss is negative once the reward separates the data.
                improved = best_loss - loss > MIN_IMPROVEMENT * abs(best_loss)
                best_loss, best_params = loss, jax.tree.map(jnp.copy, state.params)
                stale = 0 if improved else stale + 1
            else:
                stale += 1
        state = RewardState(params=best_params, opt_state=state.opt_state)
        return state, {
            **metrics,
            "reward/train_loss": train_loss,
            "reward/holdout_loss": best_loss,
            "reward/epochs": float(epochs),
        }


#: Each leader's data and budget: (keeps_history, budget).
LEADERS: dict[str, tuple[bool, Budget]] = {
    "pal": (False, "holdout"),
    "ral": (True, "passes"),
    "gda": (False, "fixed"),
    "gda-replay": (True, "fixed"),
    "reward-first": (False, "opening"),
}


def make_leader(
    name: LeaderName,
    config: LeaderConfig,
    budget: Budget | None = None,
    rows: BudgetRows = "real",
    policy_updates: int = 1000,
    method_steps: int | None = None,
) -> Leader:
    """The leader ``name`` with ``config``; ``budget`` swaps in another budget (App. D's ablation swaps
    PAL's and RAL's); ``policy_updates`` is ``n_pol``; ``method_steps`` the method's own fixed budget."""
    keeps_history, own_budget = LEADERS[name]
    return Leader(keeps_history, budget or own_budget, config, rows, policy_updates, method_steps)
