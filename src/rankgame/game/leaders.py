"""Who leads the Stackelberg game (Sec. 4.3, App. B.2): which agent data the reward sees, and how long it trains.

* PAL (policy as leader): the reward is fit *to convergence* on the current iteration's agent data
  only, judged by a shuffled holdout (Alg. 2).
* RAL (reward as leader): the reward is fit on *all* agent data so far, with ``n_rew = |D| / batch``
  gradient steps per iteration (Alg. 3, Table 4), times ``RewardConfig.ral_passes`` and rounded up to
  whole fused chunks (``RewardConfig.chunk``, 8 steps). By default ``|D|`` counts the real agent states
  collected so far, not the absorbing states that pad short episodes: padding multiplies the budget of
  an early phase full of short episodes by up to H / (episode length) (``RewardConfig.budget_rows =
  "all"`` counts it, as the authors' code does). Each
  gradient step draws one mixture per sampled state, so with the default grid one pass covers a sixth
  of the mixtures. RAL holds out the same shuffled share of agent rows (time steps) as PAL
  (``holdout_fraction``), only to log a holdout loss; it trains on the rest.

``RewardConfig.budget`` can swap the two budgets (App. D, Stackelberg game design): a PAL reward
trained for a fixed number of passes, or a RAL reward trained until its holdout stops improving.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rankgame.reward.player import RewardPlayer, RewardState
from rankgame.reward.ranking_data import RankingData


def add_agent_data(
    leader: str, data: RankingData, trajectories: Sequence[np.ndarray], rng: np.random.Generator
) -> None:
    """PAL discards older agent data; RAL aggregates it."""
    if leader == "pal":
        data.clear()
    data.add(trajectories, rng)


def fit_reward(
    leader: str, player: RewardPlayer, state: RewardState, data: RankingData, rng: np.random.Generator
) -> tuple[RewardState, dict[str, float]]:
    """One reward-player turn with the leader's budget, or the one ``RewardConfig.budget`` names."""
    cfg = player.config
    budget = cfg.budget if cfg.budget != "leader" else ("holdout" if leader == "pal" else "passes")
    if budget == "holdout":
        return player.fit_until_converged(state, data, rng)
    rows = data.n_real_states if cfg.budget_rows == "real" else len(data.train_rows)
    n_updates = max(1, math.ceil(cfg.ral_passes * rows / cfg.batch_size))
    state, train_loss = player.fit_steps(state, data, n_updates, rng)
    return state, {
        "reward/train_loss": train_loss,
        "reward/holdout_loss": player.holdout_loss(state.params, data),
        "reward/epochs": float("nan"),
    }
