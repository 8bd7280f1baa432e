"""A tiny continuous task with a known optimal policy, for fast learning tests and examples.

``rankgame/PointGoal-v0``: a point on a line starts at a random position in ``[-1, 1]`` and must
move to the goal at ``x = 0.5`` and stay there. Observation ``(x, goal - x)``, action ``a`` in
``[-1, 1]``, dynamics ``x' = clip(x + 0.2 a, -2, 2)``, reward ``-|x' - goal|``, 40 steps per
episode with no early termination. :func:`point_goal_expert` is the analytic expert: a proportional
controller that reaches the goal in at most a few steps.

``rankgame/PointGoalEdge-v0``: the same task on a ledge; an episode terminates early when the point
steps past ``|x| > 1.5``. Since every reward is negative, stepping off early is a shortcut for the
true reward; it exercises the absorbing-state handling of early-terminated episodes.

``rankgame/PointGoalMirrored-v0``: the same task with the goal at ``x = -0.5``, a changed intent for
tests of non-stationary imitation (``rankgame train --switch-at``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

POINT_GOAL_ID = "rankgame/PointGoal-v0"
POINT_GOAL_EDGE_ID = "rankgame/PointGoalEdge-v0"
POINT_GOAL_MIRRORED_ID = "rankgame/PointGoalMirrored-v0"
GOAL = 0.5
STEP_SIZE = 0.2
HORIZON = 40
EDGE = 1.5


class PointGoalEnv(gym.Env):
    """See the module docstring."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (2,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, edge: float | None = None, goal: float = GOAL) -> None:
        self._x = 0.0
        self._edge = edge
        self._goal = goal

    def _obs(self) -> np.ndarray:
        return np.array([self._x, self._goal - self._x], np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self._x = float(self.np_random.uniform(-1.0, 1.0))
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        act = float(np.clip(np.asarray(action).reshape(-1)[0], -1.0, 1.0))
        self._x = float(np.clip(self._x + STEP_SIZE * act, -2.0, 2.0))
        fell = self._edge is not None and abs(self._x) > self._edge
        return self._obs(), -abs(self._x - self._goal), fell, False, {}


def point_goal_expert(obs: np.ndarray) -> np.ndarray:
    """Optimal action ``(1,)`` for an observation ``(2,)`` of any of the tasks: step straight at the goal."""
    return np.clip(np.array([obs[1] / STEP_SIZE], np.float32), -1.0, 1.0)


def register_toy_envs() -> None:
    """Register the toy tasks with Gymnasium (idempotent)."""
    if POINT_GOAL_ID not in gym.registry:
        gym.register(POINT_GOAL_ID, entry_point=PointGoalEnv, max_episode_steps=HORIZON)
    if POINT_GOAL_EDGE_ID not in gym.registry:
        gym.register(POINT_GOAL_EDGE_ID, entry_point=PointGoalEnv, max_episode_steps=HORIZON, kwargs={"edge": EDGE})
    if POINT_GOAL_MIRRORED_ID not in gym.registry:
        mirrored = {"goal": -GOAL}
        gym.register(POINT_GOAL_MIRRORED_ID, entry_point=PointGoalEnv, max_episode_steps=HORIZON, kwargs=mirrored)
