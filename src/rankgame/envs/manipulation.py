"""The paper's dexterous manipulation task, Pen (Sec. 5.2, App. D), on current Gymnasium-Robotics.

``rankgame/Pen-v0`` is the Adroit hand reorienting a pen to a random target orientation, as the
paper's mjrl ``pen-v0``: the dynamics, observation (45 entries) and dense reward of Gymnasium-Robotics'
``AdroitHandPen-v1``, with pen-v0's 100-step episodes that end as soon as the pen falls (its height,
observation entry 26, below 0.075 m). ``AdroitHandPen-v1`` itself runs 200 steps and never ends early.
``info["success"]`` marks steps with the pen at the target position and orientation.

It needs the ``manipulation`` extra (``pip install 'rankgame[manipulation]'``); the error says so when
it is missing.
"""

from __future__ import annotations

import contextlib
import io
from typing import Any

import gymnasium as gym
import numpy as np

from rankgame.errors import RankGameError

PEN_ID = "rankgame/Pen-v0"
#: Episode length of mjrl's pen-v0.
PEN_HORIZON = 100
#: Observation entry holding the pen's height, and the height below which it has fallen (pen-v0).
PEN_HEIGHT_INDEX = 26
PEN_DROP_HEIGHT = 0.075


class EndWhenPenFalls(gym.Wrapper):
    """Terminate the episode once the pen's height drops below :data:`PEN_DROP_HEIGHT`."""

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        fallen = bool(obs[PEN_HEIGHT_INDEX] < PEN_DROP_HEIGHT)
        return obs, reward, terminated or fallen, truncated, info


def make_pen(**kwargs: Any) -> gym.Env:
    """``AdroitHandPen-v1`` with the dense reward, ending when the pen falls (the time limit is the
    registration's)."""
    try:
        # Importing the package prints a notice about reward changes of its Door, Hammer and Relocate
        # tasks, which Pen does not concern.
        with contextlib.redirect_stderr(io.StringIO()):
            from gymnasium_robotics.envs.adroit_hand.adroit_pen import AdroitHandPenEnv
    except ImportError:
        raise RankGameError(f"{PEN_ID} needs Gymnasium-Robotics: pip install 'rankgame[manipulation]'") from None
    return EndWhenPenFalls(AdroitHandPenEnv(reward_type="dense", **kwargs))


def register_manipulation_envs() -> None:
    """Register ``rankgame/Pen-v0`` with Gymnasium (idempotent; Gymnasium-Robotics is imported only
    when the task is made)."""
    if PEN_ID not in gym.registry:
        gym.register(PEN_ID, entry_point=make_pen, max_episode_steps=PEN_HORIZON)
