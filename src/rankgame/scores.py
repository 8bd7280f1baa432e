"""Scoring a policy against its expert, shared by every trainer of ``rankgame train``.

The normalized score is ``100 (return - random) / (expert - random)`` (the paper's normalization): the
expert's return is the mean over its file's trajectories, the random policy's comes from the file's
``random_return_mean`` record, or is measured on the evaluation environment when the file has none.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from rankgame.data.experts import normalized_score
from rankgame.data.trajectories import Trajectory, TrajectoryFile
from rankgame.envs.rollout import PolicyFn, episode_returns, random_policy, run_episodes, success_postfix, success_rate

#: The first columns of every ``rankgame train`` run's ``metrics.csv``: the harness's step count and
#: clock, then the evaluation row of :meth:`ScoreScale.evaluate`.
EVAL_COLUMNS = ("env_steps", "wall_s", "steps_per_s", "eval_return", "normalized_score", "eval_success")

#: Episodes of the random policy when the expert file records no random return.
RANDOM_EPISODES = 20


@dataclass(frozen=True)
class ScoreScale:
    """The returns that normalize scores: the expert's and the random policy's."""

    expert_return: float
    random_return: float

    @classmethod
    def of(cls, expert: TrajectoryFile, eval_env: gym.Env, seed: int) -> ScoreScale:
        """The scale of ``expert``'s file (measuring the random return on ``eval_env`` if it has none)."""
        random_return = float(expert.metadata.get("random_return_mean", np.nan))
        if not np.isfinite(random_return):
            policy = random_policy(eval_env, seed)
            random_return = float(episode_returns(eval_env, policy, RANDOM_EPISODES, seed).mean())
        scale = cls(float(expert.returns.mean()), random_return)
        if scale.expert_return == scale.random_return:
            print("expert and random returns are equal: the normalized score is not defined", file=sys.stderr)
        return scale

    def evaluate(self, eval_env: gym.Env, policy: PolicyFn, episodes: int, seed: int) -> dict[str, float]:
        """:meth:`score` of ``policy``'s ``episodes`` episodes reset from ``seed + i``."""
        return self.score(*run_episodes(eval_env, policy, episodes, seed))

    def score(self, episodes: list[Trajectory], success_steps: list[int | None]) -> dict[str, float]:
        """The mean true return of recorded episodes (:func:`~rankgame.envs.rollout.run_episodes`), its
        normalized score and, for tasks that report success, the success rate (``eval_return``,
        ``normalized_score``, ``eval_success``)."""
        mean = float(np.mean([episode.ret for episode in episodes]))
        row = {
            "eval_return": mean,
            "normalized_score": float(normalized_score(mean, self.expert_return, self.random_return)),
        }
        success = success_rate(success_steps)
        return row if success is None else {**row, "eval_success": success}


def score_postfix(row: dict[str, float]) -> dict[str, str]:
    """Progress-bar fields of an evaluation row: normalized score, return and, where known, success rate."""
    return {
        "score": f"{row['normalized_score']:.1f}",
        "ret": f"{row['eval_return']:.0f}",
        **success_postfix(row.get("eval_success")),
    }
