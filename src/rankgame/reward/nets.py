"""The reward network: a ReLU MLP from reward inputs ``(B, d)`` to raw rewards ``(B,)``."""

from __future__ import annotations

import flax.linen as nn
import jax
import numpy as np

from rankgame.nets import MLP, SpectralDense


class RewardNet(nn.Module):
    """ReLU MLP ``features (B, d) -> raw reward (B,)`` (every hidden layer has its activation).

    ``columns``, if given, are the entries of each input row the network reads (see
    :meth:`rankgame.reward.inputs.InputLayout.columns`); the others are ignored. ``spectral_norm``
    normalizes every layer, the output layer included, by its spectral norm (the regularizer
    ablation, App. D), so the reward is 1-Lipschitz in its inputs.
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
