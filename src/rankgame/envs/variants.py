"""Changed versions of Gymnasium tasks.

For the paper's non-stationary imitation experiments (Sec. 5.3), two versions of Hopper-v5:

* ``rankgame/HopperBackward-v5``: the same robot, rewarded for hopping *backward*
  (``forward_reward_weight = -1``): an expert of this task demonstrates a changed intent.
* ``rankgame/HopperHeavy-v5``: every body 1.2 times as heavy (masses and inertias): changed dynamics
  under the same intent.

Both keep Hopper-v5's observation and action spaces, termination and 1000-step horizon, so a run
can switch to them mid-training (``rankgame train --switch-at``).

And Ant-v5 and Humanoid-v5 as the paper's gym ``-v2`` versions of them were observed:

* ``rankgame/AntNoContact-v5`` and ``rankgame/HumanoidNoContact-v5``: the same tasks without the
  external contact forces at the end of their observations (``include_cfrc_ext_in_observation=False``:
  Ant keeps its first 27 entries of 105, Humanoid its first 270 of 348). Gym's Ant-v2 and Humanoid-v2
  reported those forces as zeros. Humanoid's reach thousands where its other entries stay within
  hundreds; Ant's are clipped to [-1, 1] but make up 78 of its 105 entries. Everything else
  (dynamics, reward, termination, horizon) is the original task's, so its expert data serves with the
  forces left out (:data:`OBS_PREFIX_VARIANTS`).
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.envs.mujoco.hopper_v5 import HopperEnv

HOPPER_BACKWARD_ID = "rankgame/HopperBackward-v5"
HOPPER_HEAVY_ID = "rankgame/HopperHeavy-v5"
#: Factor on every body's mass and inertia in ``rankgame/HopperHeavy-v5`` (the paper's 1.2).
HEAVY_MASS_SCALE = 1.2
ANT_NO_CONTACT_ID = "rankgame/AntNoContact-v5"
HUMANOID_NO_CONTACT_ID = "rankgame/HumanoidNoContact-v5"
#: Tasks that are another task observed through its leading entries only: id -> (that task, entries kept).
OBS_PREFIX_VARIANTS: dict[str, tuple[str, int]] = {
    ANT_NO_CONTACT_ID: ("Ant-v5", 27),
    HUMANOID_NO_CONTACT_ID: ("Humanoid-v5", 270),
}


class HeavyHopperEnv(HopperEnv):
    """Hopper-v5 with every body's mass and inertia multiplied by ``mass_scale``."""

    def __init__(self, mass_scale: float = HEAVY_MASS_SCALE, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.model.body_mass[:] *= mass_scale
        self.model.body_inertia[:] *= mass_scale


def register_variant_envs() -> None:
    """Register the variants with Gymnasium (idempotent)."""
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
    for env_id, (source_id, _) in OBS_PREFIX_VARIANTS.items():
        if env_id not in gym.registry:
            source = gym.spec(source_id)
            gym.register(
                env_id,
                entry_point=source.entry_point,
                max_episode_steps=source.max_episode_steps,
                kwargs={**source.kwargs, "include_cfrc_ext_in_observation": False},
            )
