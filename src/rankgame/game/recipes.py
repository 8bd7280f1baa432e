"""Per-task settings of ``rankgame train --recipe``.

``paper`` keeps the paper's common hyperparameters (Table 4) on every task. ``tuned`` changes, for the
task and method pairs of :data:`TUNED`, the settings that measured better on this implementation;
every other pair keeps the paper's values. The evidence for each entry is in docs/recipes.md. The
CLI applies a recipe to the defaults, so an option given on the command line overrides it.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Literal, TypeVar

Recipe = Literal["paper", "tuned"]
RECIPES: tuple[Recipe, ...] = ("paper", "tuned")

#: Settings of ``--recipe tuned`` per (task, method), by option name (``reward.lr`` is ``--reward.lr``).
TUNED: dict[tuple[str, str], dict[str, Any]] = {
    ("Ant-v5", "rank-pal-auto"): {"reward_obs": "0:27"},
    ("Ant-v5", "rank-ral-auto"): {"reward_obs": "0:27", "leader.ral_passes": 6.0, "sac.updates_per_step": 2.0},
    ("rankgame/AntNoContact-v5", "rank-ral-auto"): {"leader.ral_passes": 6.0, "sac.updates_per_step": 2.0},
    ("Hopper-v5", "rank-pal-auto"): {"rankings.k": 1.0, "reward.r_max": 1.0, "leader.patience": 1},
    ("Hopper-v5", "rank-ral-auto"): {"rankings.k": 1.0, "reward.r_max": 1.0, "sac.updates_per_step": 2.0},
    ("HalfCheetah-v5", "rank-pal-auto"): {"reward.lr": 1e-4, "reward.weight_decay": 1e-2},
    ("Humanoid-v5", "rank-pal-auto"): {"reward.lr": 1e-4, "reward.weight_decay": 1e-2},
    ("rankgame/HumanoidNoContact-v5", "rank-pal-auto"): {"reward.lr": 1e-4, "reward.weight_decay": 1e-2},
    ("Walker2d-v5", "rank-pal-auto"): {"leader.patience": 1},
    ("Walker2d-v5", "rank-ral-auto"): {"leader.ral_passes": 6.0, "sac.updates_per_step": 2.0},
}

Config = TypeVar("Config")


def recipe_settings(recipe: str, env: str, method: str) -> dict[str, Any]:
    """The settings ``recipe`` changes for ``method`` on ``env`` (empty when it keeps the paper's)."""
    if recipe not in RECIPES:
        raise ValueError(f"unknown recipe {recipe!r}; choose from {', '.join(RECIPES)}")
    return dict(TUNED.get((env, method), {})) if recipe == "tuned" else {}


def with_settings(config: Config, settings: dict[str, Any]) -> Config:
    """``config`` (a dataclass) with dotted option names set: ``{"reward.lr": 1e-4}`` sets ``config.reward.lr``."""
    nested: dict[str, dict[str, Any]] = {}
    top: dict[str, Any] = {}
    for name, value in settings.items():
        head, _, rest = name.partition(".")
        if rest:
            nested.setdefault(head, {})[rest] = value
        else:
            top[head] = value
    for head, inner in nested.items():
        top[head] = with_settings(getattr(config, head), inner)
    return dataclasses.replace(config, **top)


def setting_value(config: object, name: str) -> Any:
    """The value of a dotted option name in ``config``: ``"reward.lr"`` gives ``config.reward.lr``."""
    return functools.reduce(getattr, name.split("."), config)
