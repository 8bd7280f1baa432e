"""Changed versions of Hopper-v5 for the paper's non-stationary imitation experiments (Sec. 5.3).

* ``rankgame/HopperBackward-v5``: the same robot, rewarded for hopping *backward*
  (``forward_reward_weight = -1``): an expert of this task demonstrates a changed intent.
* ``rankgame/HopperHeavy-v5``: every body 1.2 times as heavy (masses and inertias): changed dynamics
  under the same intent.

Both keep Hopper-v5's observation and action spaces, termination and 1000-step horizon, so a run
can switch to them mid-training (``rankgame train --switch-at``).
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.envs.mujoco.hopper_v5 import HopperEnv

HOPPER_BACKWARD_ID = "rankgame/HopperBackward-v5"
HOPPER_HEAVY_ID = "rankgame/HopperHeavy-v5"
#: Factor on every body's mass and inertia in ``rankgame/HopperHeavy-v5`` (the paper's 1.2).
HEAVY_MASS_SCALE = 1.2


class HeavyHopperEnv(HopperEnv):
    """Hopper-v5 with every body's mass and inertia multiplied by ``mass_scale``."""

    def __init__(self, mass_scale: float = HEAVY_MASS_SCALE, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.model.body_mass[:] *= mass_scale
        self.model.body_inertia[:] *= mass_scale


def register_variant_envs() -> None:
    """Register the Hopper variants with Gymnasium (idempotent)."""
    horizon = gym.spec("Hopper-v5").max_episode_steps
    if HOPPER_BACKWARD_ID not in gym.registry:
        gym.register(
            HOPPER_BACKWARD_ID,
            entry_point=HopperEnv,
            max_episode_steps=horizon,
            kwargs={"forward_reward_weight": -1.0},
        )
    if HOPPER_HEAVY_ID not in gym.registry:
        gym.register(HOPPER_HEAVY_ID, entry_point=HeavyHopperEnv, max_episode_steps=horizon)
