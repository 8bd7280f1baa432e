"""The policy players a method can name (the ``policy`` column of :data:`rankgame.game.methods.METHODS`).

Each drives one environment the same way: ``env_step()`` once per environment step, then
``maybe_update(reward_params)``, with every batch relabelled by the game's current reward; all use
absorbing states (:mod:`rankgame.absorbing`) and save their actor in the same file format.

* ``sac``: :class:`~rankgame.policy.learner.SACLearner`, off-policy, the ranking game's player
  (``--sac.*``); an iteration of the game is ``n_pol = H`` steps by default.
* ``ppo``: :class:`~rankgame.policy.ppo_learner.PPOLearner`, on-policy, GAIL's and GAIfO's player
  (``--ppo.*``); an iteration is one rollout of ``--ppo.rollout-steps`` by default, so the reward
  moves between two PPO updates.
* ``opolo``: :class:`~rankgame.policy.opolo.OPOLOLearner`, off-policy TD3 with OPOLO's objectives and
  inverse action model (``--td3.*``, ``--opolo.*``), which reads the expert's state transitions; an
  iteration is ``H`` steps.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import gymnasium as gym

from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import RewardFn

if TYPE_CHECKING:
    from rankgame.config import TrainConfig
    from rankgame.data.trajectories import Trajectory


def make_policy_player(
    name: str, env: gym.Env, config: TrainConfig, reward_fn: RewardFn, expert: Sequence[Trajectory]
) -> Any:
    """The policy player ``name`` (``sac``, ``ppo`` or ``opolo``) acting in ``env``, paid by ``reward_fn``;
    ``expert`` holds the imitated trajectories (read by ``opolo`` only)."""
    if name == "opolo":
        from rankgame.policy.opolo import OPOLOLearner

        return OPOLOLearner(env, config.td3, config.opolo, config.seed, reward_fn, expert, config.env)
    if name == "ppo":
        from rankgame.policy.ppo_learner import PPOLearner

        return PPOLearner(env, config.ppo, config.seed, reward_fn=reward_fn, absorbing=True)
    return SACLearner(env, config.sac, config.seed, reward_fn=reward_fn, store_env_reward=False, absorbing=True)


def iteration_steps(name: str, config: TrainConfig, horizon: int) -> int:
    """Environment steps of one game iteration by default: a PPO rollout, else the horizon H."""
    return config.ppo.rollout_steps if name == "ppo" else horizon
