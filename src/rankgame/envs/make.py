"""Environment factory: one entry point for every continuous-control task rankgame runs on.

The MuJoCo locomotion tasks of the paper (Hopper, HalfCheetah, Walker2d, Ant, Humanoid, Swimmer)
are used in their Gymnasium ``-v5`` versions; any other registered Gymnasium id with a
continuous (``Box``) action space works too.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from rankgame.errors import RankGameError

#: The locomotion tasks the paper evaluates on, in their current Gymnasium versions.
LOCOMOTION_TASKS: tuple[str, ...] = (
    "Hopper-v5",
    "HalfCheetah-v5",
    "Walker2d-v5",
    "Ant-v5",
    "Humanoid-v5",
    "Swimmer-v5",
)


@dataclass(frozen=True)
class EnvSpec:
    """Shapes and limits of a task, enough to build networks and buffers without an env."""

    env_id: str
    obs_dim: int
    act_dim: int
    act_low: np.ndarray  # (act_dim,)
    act_high: np.ndarray  # (act_dim,)
    max_episode_steps: int | None


def make_env(env_id: str, **kwargs: object) -> gym.Env:
    """Create a Gymnasium environment with a flat continuous observation and action space.

    Raises:
        RankGameError: the id is unknown, or the task's spaces are not flat ``Box`` spaces.
    """
    try:
        env = gym.make(env_id, **kwargs)
    except gym.error.Error as exc:
        known = ", ".join(LOCOMOTION_TASKS)
        raise RankGameError(f"unknown environment id {env_id!r} ({exc}); try one of: {known}") from None
    except TypeError as exc:
        raise RankGameError(f"environment {env_id!r} rejected its options: {exc}") from None
    if not isinstance(env.action_space, gym.spaces.Box):
        env.close()
        raise RankGameError(
            f"environment {env_id!r} has a {type(env.action_space).__name__} action space; "
            "rankgame needs continuous (Box) actions"
        )
    if not isinstance(env.observation_space, gym.spaces.Box) or len(env.observation_space.shape) != 1:
        env.close()
        raise RankGameError(f"environment {env_id!r} needs a flat Box observation space")
    return env


def env_spec(env: gym.Env) -> EnvSpec:
    """Read the :class:`EnvSpec` of an environment made by :func:`make_env`."""
    act_space = env.action_space
    assert isinstance(act_space, gym.spaces.Box)
    spec = env.spec
    return EnvSpec(
        env_id=spec.id if spec is not None else type(env.unwrapped).__name__,
        obs_dim=int(env.observation_space.shape[0]),
        act_dim=int(act_space.shape[0]),
        act_low=np.asarray(act_space.low, dtype=np.float32),
        act_high=np.asarray(act_space.high, dtype=np.float32),
        max_episode_steps=spec.max_episode_steps if spec is not None else None,
    )
