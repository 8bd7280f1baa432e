"""The paper's manipulation tasks (Sec. 5.2, App. D): Pen on Gymnasium-Robotics, Door on robosuite.

``rankgame/Pen-v0`` is the Adroit hand reorienting a pen to a random target orientation, as the
paper's mjrl ``pen-v0``: the dynamics, observation (45 entries) and dense reward of Gymnasium-Robotics'
``AdroitHandPen-v1``, with pen-v0's 100-step episodes that end as soon as the pen falls (its height,
observation entry 26, below 0.075 m). ``AdroitHandPen-v1`` itself runs 200 steps and never ends early.
``info["success"]`` marks steps with the pen at the target position and orientation.

It needs the ``manipulation`` extra (``pip install 'rankgame[manipulation]'``); the error says so when
it is missing.

``rankgame/Door-v0`` is robosuite's Door with a Panda arm, as in the paper: the arm (operational-space
pose control, 7 action entries with the gripper) opens a door whose position varies per episode. The
observation is robosuite's flat robot state (43 entries: joint angles as cosine and sine, joint
velocities, end-effector pose, gripper) followed by the object state (14: door and handle positions,
their offsets from the gripper, hinge and handle angles), 57 in all. The reward is robosuite's shaped
reward (at most 1 per step). Episodes run 200 steps, the door horizon of the authors' fixed-horizon
wrapper, and never end early; ``info["success"]`` marks steps with the door open (hinge angle above
0.3 rad). It needs the ``door`` extra (``pip install 'rankgame[door]'``).
"""

from __future__ import annotations

import contextlib
import io
import logging
import sys
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


DOOR_ID = "rankgame/Door-v0"
#: Episode length of Door (the authors' fixed-horizon wrapper uses 200 for their door task).
DOOR_HORIZON = 200
#: robosuite's observation groups that make up the flat observation, in this order.
DOOR_OBS_KEYS = ("robot0_proprio-state", "object-state")


def _import_robosuite() -> Any:
    """robosuite, imported without its start-up notices (missing private macros, optional robot
    models), its later log messages limited to errors."""
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            import robosuite
    except ImportError:
        raise RankGameError(f"{DOOR_ID} needs robosuite: pip install 'rankgame[door]'") from None
    logger = logging.getLogger("robosuite_logs")
    logger.setLevel(logging.ERROR)
    for handler in logger.handlers:
        if isinstance(handler, logging.StreamHandler) and not isinstance(handler, logging.FileHandler):
            handler.setStream(sys.stderr)
    return robosuite


class DoorEnv(gym.Env):
    """robosuite's Door with a Panda arm as a Gymnasium task (see the module docstring).

    robosuite places the door and perturbs the arm's initial joints with NumPy's global generator.
    Each task keeps its own generator state, seeded by ``reset(seed=s)``, and swaps it in for the
    reset only, so equal seeds give equal episodes and two tasks (training and evaluation) do not
    draw from each other's stream.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self) -> None:
        robosuite = _import_robosuite()
        with contextlib.redirect_stderr(io.StringIO()):  # controller-configuration notices
            self._door = robosuite.make(
                "Door",
                robots="Panda",
                has_renderer=False,
                has_offscreen_renderer=False,
                use_camera_obs=False,
                reward_shaping=True,
                control_freq=20,
                horizon=DOOR_HORIZON,
                ignore_done=True,  # the time limit is the registration's
                hard_reset=False,  # a hard reset rebuilds the whole simulation every episode
            )
        low, high = self._door.action_spec
        self.action_space = gym.spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        obs_dim = sum(int(np.size(self._door.observation_spec()[key])) for key in DOOR_OBS_KEYS)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(obs_dim,), dtype=np.float64)
        self._numpy_state = np.random.RandomState(0).get_state()

    @staticmethod
    def _flat(observation: dict[str, np.ndarray]) -> np.ndarray:
        return np.concatenate([np.asarray(observation[key], dtype=np.float64) for key in DOOR_OBS_KEYS])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        if seed is not None:
            self._numpy_state = np.random.RandomState(seed).get_state()
        outside = np.random.get_state()
        np.random.set_state(self._numpy_state)
        try:
            observation = self._door.reset()
        finally:
            self._numpy_state = np.random.get_state()
            np.random.set_state(outside)
        return self._flat(observation), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = np.clip(action, self.action_space.low, self.action_space.high)
        observation, reward, _, _ = self._door.step(action)
        return self._flat(observation), float(reward), False, False, {"success": bool(self._door._check_success())}

    def close(self) -> None:
        self._door.close()


def register_manipulation_envs() -> None:
    """Register ``rankgame/Pen-v0`` and ``rankgame/Door-v0`` with Gymnasium (idempotent; their packages
    are imported only when a task is made)."""
    if PEN_ID not in gym.registry:
        gym.register(PEN_ID, entry_point=make_pen, max_episode_steps=PEN_HORIZON)
    if DOOR_ID not in gym.registry:
        gym.register(DOOR_ID, entry_point=DoorEnv, max_episode_steps=DOOR_HORIZON)
