"""Networks shared by both players: the ReLU MLP and the spectrally normalized dense layer."""

from __future__ import annotations

import flax.linen as nn
import jax
import jax.numpy as jnp


class MLP(nn.Module):
    """ReLU MLP ``(B, n_in) -> (B, out_dim)`` with a linear output layer (Flax's default initializers:
    truncated-normal weights of variance 1 / fan_in, zero biases)."""

    hidden_sizes: tuple[int, ...]
    out_dim: int

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for width in self.hidden_sizes:
            x = nn.relu(nn.Dense(width)(x))
        return nn.Dense(self.out_dim)(x)


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
