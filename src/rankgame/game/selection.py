"""Which policy a game run hands over, chosen from the learned reward and the expert data alone.

The policy of a run's last evaluation is sometimes a collapsed one (a policy player that fell; see the
notebook's stability study). At every evaluation the game also scores the evaluation episodes with the
reward player's current reward, with no true reward involved, as the share of the expert's learned
return they collect over the horizon:

    ratio = mean_{episodes, t < H} r(x_t) / mean_{expert trajectories, t < H} r(x_t),

each episode padded with the absorbing state to the horizon ``H`` (so an episode that fell early
collects the absorbing state's reward for the rest of it). The ratio is logged as
:data:`SELECTION_COLUMN` in ``metrics.csv``, and the actor of the evaluation where it is largest (the
latest of equals) is kept as :data:`SELECTED_POLICY_NAME` in the run folder. The criterion starts
again after a task or expert switch (a policy of the old task is not one of the new).

The ratio is defined only where the expert's learned reward is positive (the rank methods' rewards
lie in ``[0, k]``); elsewhere it is NaN and no policy is selected at that evaluation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from rankgame.errors import RankGameError
from rankgame.plot import read_curve

#: The selected actor in a run folder (``rankgame evaluate --policy RUN/selected_policy.msgpack``).
SELECTED_POLICY_NAME = "selected_policy.msgpack"
#: The ``metrics.csv`` column of the selection criterion.
SELECTION_COLUMN = "selection/learned_return"


def learned_return_ratio(policy_reward: float, expert_reward: float) -> float:
    """The selection criterion from the mean learned reward ``()`` of the evaluation episodes' padded
    inputs and of the expert's (both over ``H`` steps per trajectory); NaN unless ``expert_reward > 0``
    and both are finite. Rounded to the 6 significant digits that ``metrics.csv`` keeps, so that the
    saved policy and :func:`selected_evaluation` pick the same evaluation."""
    if not (math.isfinite(policy_reward) and math.isfinite(expert_reward)) or expert_reward <= 0.0:
        return math.nan
    return float(f"{policy_reward / expert_reward:.6g}")


@dataclass
class PolicySelection:
    """The best criterion so far (None before the first defined one)."""

    best: float | None = None

    def improves(self, ratio: float) -> bool:
        """Whether ``ratio`` is defined and at least the best so far; if so it becomes the best."""
        if not math.isfinite(ratio) or (self.best is not None and ratio < self.best):
            return False
        self.best = ratio
        return True

    def reset(self) -> None:
        """Forget the past evaluations (after a task or expert switch)."""
        self.best = None


@dataclass(frozen=True)
class SelectedEvaluation:
    """The evaluation a run selected: its step, criterion and (true-reward) normalized score."""

    env_steps: int
    learned_return: float
    normalized_score: float


def selected_evaluation(run: Path, since: int = 0) -> SelectedEvaluation | None:
    """The evaluation of ``run/metrics.csv`` that :class:`PolicySelection` picked among those after step
    ``since`` (a switch); None for a run without the column or with no defined criterion after ``since``."""
    try:
        steps, ratios = read_curve(Path(run), SELECTION_COLUMN)
    except RankGameError:  # a run of another trainer, or of a version before selection
        return None
    scores = dict(zip(*read_curve(Path(run), "normalized_score"), strict=True))
    later = [(ratio, step) for step, ratio in zip(steps, ratios, strict=True) if step > since and math.isfinite(ratio)]
    if not later:
        return None
    ratio, step = max(later)  # the largest, the latest of equals
    return SelectedEvaluation(step, ratio, scores.get(step, math.nan))
