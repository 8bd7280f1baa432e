"""rankgame: imitation learning as a ranking game (Sikchi, Saran, Goo, Niekum; TMLR 2023).

The public API::

    from rankgame import TrainConfig, export_reward, load_reward, train

    summary = train(TrainConfig(env="Hopper-v5", steps=50_000, out="runs/demo"))
    reward = load_reward(export_reward("runs/demo", "runs/demo/reward.msgpack"))

Names are imported on first use, so that ``import rankgame`` (and the command line) stays fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: Public name -> the module that defines it.
_EXPORTS = {
    "train": "rankgame.training",
    "TrainConfig": "rankgame.config",
    "RankingsConfig": "rankgame.game.rankings",
    "RewardConfig": "rankgame.reward.player",
    "LeaderConfig": "rankgame.game.leaders",
    "SACConfig": "rankgame.policy.sac",
    "SwitchConfig": "rankgame.config",
    "AblationConfig": "rankgame.config",
    "METHODS": "rankgame.game.methods",
    "Method": "rankgame.game.methods",
    "load_policy": "rankgame.policy.io",
    "export_reward": "rankgame.reward.export",
    "load_reward": "rankgame.reward.export",
    "LearnedReward": "rankgame.reward.export",
    "Trajectory": "rankgame.data.trajectories",
    "TrajectoryFile": "rankgame.data.trajectories",
    "load_trajectories": "rankgame.data.trajectories",
    "save_trajectories": "rankgame.data.trajectories",
    "make_env": "rankgame.envs.make",
    "RankGameError": "rankgame.errors",
}

__all__ = [
    "AblationConfig",
    "LeaderConfig",
    "LearnedReward",
    "METHODS",
    "Method",
    "RankGameError",
    "RankingsConfig",
    "RewardConfig",
    "SACConfig",
    "SwitchConfig",
    "TrainConfig",
    "Trajectory",
    "TrajectoryFile",
    "export_reward",
    "load_policy",
    "load_reward",
    "load_trajectories",
    "make_env",
    "save_trajectories",
    "train",
]


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'rankgame' has no attribute {name!r}")
    module = importlib.import_module(_EXPORTS[name])
    value = getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return [*globals(), *__all__]


if TYPE_CHECKING:
    from rankgame.config import AblationConfig, SwitchConfig, TrainConfig
    from rankgame.data.trajectories import Trajectory, TrajectoryFile, load_trajectories, save_trajectories
    from rankgame.envs.make import make_env
    from rankgame.errors import RankGameError
    from rankgame.game.leaders import LeaderConfig
    from rankgame.game.methods import METHODS, Method
    from rankgame.game.rankings import RankingsConfig
    from rankgame.policy.io import load_policy
    from rankgame.policy.sac import SACConfig
    from rankgame.reward.export import LearnedReward, export_reward, load_reward
    from rankgame.reward.player import RewardConfig
    from rankgame.training import train
