"""The reward network and how its inputs are built (LfO: r(s) or r(s, s'); LfD: r(s, a)).

Inputs always carry an *absorbing flag* as their last observation entry (0 for real states, 1 for
the absorbing state that pads early-terminated trajectories; see :mod:`rankgame.reward.features`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from rankgame.policy.sac import MLP

RewardInput = Literal["s", "ss", "sa"]
Bound = Literal["clip", "tanh"]


class SpectralDense(nn.Module):
    """Dense layer ``(B, n_in) -> (B, features)`` whose kernel is divided by its spectral norm
    (Miyato et al., 2018), so the layer is 1-Lipschitz.

    The largest singular value is computed exactly (an SVD of the small kernel at every call) rather
    than by one power-iteration step per update with a stored vector: the result is what power
    iteration converges to, and the layer keeps no state besides its parameters. As in the usual
    implementation, the gradient treats the singular vectors as constants: sigma = u^T W v.
    """

    features: int

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        kernel = self.param("kernel", nn.initializers.lecun_normal(), (x.shape[-1], self.features))
        bias = self.param("bias", nn.initializers.zeros_init(), (self.features,))
        u, _, vt = jnp.linalg.svd(jax.lax.stop_gradient(kernel), full_matrices=False)
        sigma = u[:, 0] @ kernel @ vt[0]
        return x @ (kernel / sigma) + bias


class RewardNet(nn.Module):
    """ReLU MLP ``features (B, d) -> raw reward (B,)`` (every hidden layer has its activation).

    ``columns``, if given, are the entries of each input row the network reads (see
    :func:`feature_columns`); the others are ignored. ``spectral_norm`` normalizes every layer,
    the output layer included, by its spectral norm (the regularizer ablation, App. D), so the
    reward is 1-Lipschitz in its inputs.
    """

    hidden_sizes: tuple[int, ...] = (64, 64)
    columns: tuple[int, ...] | None = None
    spectral_norm: bool = False

    @nn.compact
    def __call__(self, features: jax.Array) -> jax.Array:
        if self.columns is not None:
            features = features[..., np.asarray(self.columns)]
        if not self.spectral_norm:
            return MLP(self.hidden_sizes, 1)(features)[..., 0]
        x = features
        for width in self.hidden_sizes:
            x = nn.relu(SpectralDense(width)(x))
        return SpectralDense(1)(x)[..., 0]


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


def parse_obs_columns(spec: str, obs_dim: int) -> tuple[int, ...]:
    """Observation entries named by ``spec``: ``all``, or indices and half-open ranges such as
    ``0:27`` or ``0:13,20:27``. Raises ``ValueError`` with a one-line reason for a bad spec."""
    if spec.strip() == "all":
        return tuple(range(obs_dim))
    columns: list[int] = []
    for item in spec.replace(",", " ").split():
        try:
            bounds = [int(part) for part in item.split(":")]
        except ValueError:
            bounds = []
        if not 1 <= len(bounds) <= 2:
            raise ValueError(f"{item!r} is neither an index nor a range like 0:27")
        start, stop = (bounds[0], bounds[0] + 1) if len(bounds) == 1 else bounds
        if not 0 <= start < stop <= obs_dim:
            raise ValueError(f"{item!r} is not a non-empty range inside the {obs_dim} observation entries")
        columns.extend(range(start, stop))
    if not columns or len(set(columns)) != len(columns):
        raise ValueError(f"{spec!r} must name each observation entry at most once, and at least one")
    return tuple(columns)


def feature_columns(
    obs_dim: int, act_dim: int, reward_input: RewardInput, obs_columns: Sequence[int]
) -> tuple[int, ...]:
    """Entries of a reward input (layout of :func:`feature_dim`) that belong to the observation
    entries ``obs_columns``: those entries and the absorbing flag of each state, and all actions."""
    flagged = [*obs_columns, obs_dim]
    if reward_input == "s":
        return tuple(flagged)
    if reward_input == "ss":
        return (*flagged, *(c + obs_dim + 1 for c in flagged))
    return (*flagged, *range(obs_dim + 1, obs_dim + 1 + act_dim))
