"""The reward network and how its inputs are built (LfO: r(s) or r(s, s'); LfD: r(s, a)).

Inputs always carry an *absorbing flag* as their last observation entry (0 for real states, 1 for
the absorbing state that pads early-terminated trajectories; see :mod:`rankgame.reward.features`).
"""

from __future__ import annotations

from typing import Literal

import flax.linen as nn
import jax
import jax.numpy as jnp

from rankgame.policy.sac import MLP

RewardInput = Literal["s", "ss", "sa"]
Bound = Literal["clip", "tanh"]


class RewardNet(nn.Module):
    """ReLU MLP ``features (B, d) -> raw reward (B,)`` (every hidden layer has its activation)."""

    hidden_sizes: tuple[int, ...] = (64, 64)

    @nn.compact
    def __call__(self, features: jax.Array) -> jax.Array:
        return MLP(self.hidden_sizes, 1)(features)[..., 0]


def bound_reward(raw: jax.Array, r_max: float, bound: Bound) -> jax.Array:
    """Map raw outputs ``(B,)`` into ``[-r_max, r_max]``: a hard ``clip`` or a smooth ``tanh``."""
    if bound == "clip":
        return jnp.clip(raw, -r_max, r_max)
    return r_max * jnp.tanh(raw / r_max)


def batch_features(batch: dict[str, jax.Array], reward_input: RewardInput) -> jax.Array:
    """Reward inputs ``(B, d)`` of a SAC batch (observations already carry the absorbing flag)."""
    if reward_input == "s":
        return batch["obs"]
    if reward_input == "ss":
        return jnp.concatenate([batch["obs"], batch["next_obs"]], axis=-1)
    return jnp.concatenate([batch["obs"], batch["acts"]], axis=-1)


def feature_dim(obs_dim: int, act_dim: int, reward_input: RewardInput) -> int:
    """Size of one reward input, absorbing flag included (``obs_dim`` excludes the flag)."""
    flagged = obs_dim + 1
    return {"s": flagged, "ss": 2 * flagged, "sa": flagged + act_dim}[reward_input]
