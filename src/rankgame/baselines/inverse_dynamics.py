"""An inverse dynamics model ``a = g(s, s')``: which action led from ``s`` to ``s'``.

BCO (Torabi, Warnell & Stone, 2018; :mod:`rankgame.baselines.bco`) learns it from the agent's own
transitions, whose actions are known, and uses it to label the expert's state transitions with the
actions the expert most likely took. The model is an MLP regression trained by the mean squared error
in the normalized action box ``[-1, 1]^act_dim`` (:func:`inverse_mse`).

The network reads ``s`` and the change ``s' - s``, each standardized with the mean and standard deviation
of the data it was last fit on (:meth:`InverseDynamics.with_statistics`): the same information as
``(s, s')``, but better conditioned when one step changes the state little. The statistics live in the
model's state, so they are saved and restored with it.
"""

from __future__ import annotations

from typing import Any

import flax.linen as nn
import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax

from rankgame.baselines.cloning import FusedUpdate, fused_fit, l2_adam
from rankgame.nets import MLP

Batch = dict[str, jax.Array]

#: Standard deviations of the inputs are floored at this before standardizing: an entry that barely
#: varies in the data (a velocity that stays 0) is then not blown up to unit scale.
STD_FLOOR = 1e-3


def inverse_mse(pred: jax.Array, acts: jax.Array) -> jax.Array:
    """Mean squared error ``()`` over all entries of predicted and true normalized actions ``(B, act_dim)``."""
    return jnp.mean((pred - acts) ** 2)


class InverseDynamicsNet(nn.Module):
    """ReLU MLP ``(obs_in (B, obs_dim), delta_in (B, obs_dim)) -> acts (B, act_dim)`` on standardized inputs."""

    hidden_sizes: tuple[int, ...]
    act_dim: int

    @nn.compact
    def __call__(self, obs_in: jax.Array, delta_in: jax.Array) -> jax.Array:
        return MLP(self.hidden_sizes, self.act_dim)(jnp.concatenate([obs_in, delta_in], axis=-1))


@flax.struct.dataclass
class InverseState:
    """The inverse model as one pytree: parameters, Adam state, the input statistics ``(obs_dim,)`` each,
    and the gradient steps taken."""

    params: Any
    opt_state: Any
    obs_mean: jax.Array
    obs_std: jax.Array
    delta_mean: jax.Array
    delta_std: jax.Array
    n_updates: jax.Array


class InverseDynamics:
    """Fit and apply ``g(s, s')``; :meth:`update` and :meth:`predict` are jitted.

    Args:
        obs_dim, act_dim: sizes of one observation and one action.
        hidden_sizes: hidden layer widths of the MLP.
        lr: Adam learning rate.
        weight_decay: L2 penalty on the parameters (see :func:`~rankgame.baselines.cloning.l2_adam`).
        batch_size: transitions per gradient step.
        chunk: gradient steps fused into one jitted call.
    """

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden_sizes: tuple[int, ...] = (256, 256),
        lr: float = 3e-4,
        weight_decay: float = 0.0,
        batch_size: int = 256,
        chunk: int = 100,
    ) -> None:
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.batch_size, self.chunk = batch_size, chunk
        self.net = InverseDynamicsNet(tuple(hidden_sizes), act_dim)
        self.tx = l2_adam(lr, weight_decay)
        self.update: FusedUpdate = jax.jit(self._update_many)
        self.predict = jax.jit(self._predict)

    def init(self, key: jax.Array) -> InverseState:
        """Fresh parameters and Adam state; unit statistics until :meth:`with_statistics`."""
        return jax.jit(self._init)(key)  # one compiled program: much faster than op-by-op on a CPU

    def _init(self, key: jax.Array) -> InverseState:
        zeros = jnp.zeros((1, self.obs_dim), jnp.float32)
        params = self.net.init(key, zeros, zeros)
        ones = jnp.ones(self.obs_dim, jnp.float32)
        return InverseState(
            params=params,
            opt_state=self.tx.init(params),
            obs_mean=jnp.zeros(self.obs_dim, jnp.float32),
            obs_std=ones,
            delta_mean=jnp.zeros(self.obs_dim, jnp.float32),
            delta_std=ones,
            n_updates=jnp.zeros((), jnp.int32),
        )

    def with_statistics(self, state: InverseState, obs: np.ndarray, next_obs: np.ndarray) -> InverseState:
        """``state`` standardizing with the mean and (floored) standard deviation of ``obs (N, obs_dim)`` and
        of ``next_obs - obs``."""
        delta = next_obs - obs

        def stats(x: np.ndarray) -> tuple[jax.Array, jax.Array]:
            mean, std = x.mean(axis=0, dtype=np.float64), x.std(axis=0, dtype=np.float64)
            return jnp.asarray(mean, jnp.float32), jnp.asarray(np.maximum(std, STD_FLOOR), jnp.float32)

        obs_mean, obs_std = stats(obs)
        delta_mean, delta_std = stats(delta)
        return state.replace(obs_mean=obs_mean, obs_std=obs_std, delta_mean=delta_mean, delta_std=delta_std)

    def apply(self, state: InverseState, params: Any, obs: jax.Array, next_obs: jax.Array) -> jax.Array:
        """Predicted normalized actions ``(B, act_dim)`` for transitions ``obs, next_obs (B, obs_dim)``."""
        obs_in = (obs - state.obs_mean) / state.obs_std
        delta_in = (next_obs - obs - state.delta_mean) / state.delta_std
        return self.net.apply(params, obs_in, delta_in)

    def _predict(self, state: InverseState, obs: jax.Array, next_obs: jax.Array) -> jax.Array:
        """:meth:`apply` with the state's own parameters (not clipped to the action box)."""
        return self.apply(state, state.params, obs, next_obs)

    def loss(self, state: InverseState, params: Any, batch: Batch) -> jax.Array:
        """:func:`inverse_mse` ``()`` of ``batch`` ``obs, next_obs (B, obs_dim)``, ``acts (B, act_dim)``."""
        return inverse_mse(self.apply(state, params, batch["obs"], batch["next_obs"]), batch["acts"])

    def _update_many(self, state: InverseState, batches: Batch) -> tuple[InverseState, jax.Array]:
        """``n`` Adam steps over ``batches`` of shape ``(n, B, ...)``; mean loss ``()``."""

        def one(carry: InverseState, batch: Batch) -> tuple[InverseState, jax.Array]:
            loss, grads = jax.value_and_grad(lambda p: self.loss(carry, p, batch))(carry.params)
            updates, opt_state = self.tx.update(grads, carry.opt_state, carry.params)
            params = optax.apply_updates(carry.params, updates)
            return carry.replace(params=params, opt_state=opt_state, n_updates=carry.n_updates + 1), loss

        state, losses = jax.lax.scan(one, state, batches)
        return state, jnp.mean(losses)

    def fit(
        self,
        state: InverseState,
        obs: np.ndarray,
        acts: np.ndarray,
        next_obs: np.ndarray,
        rng: np.random.Generator,
        n_steps: int,
    ) -> tuple[InverseState, float]:
        """``n_steps`` gradient steps on transitions ``obs, next_obs (N, obs_dim)`` with their normalized
        ``acts (N, act_dim)``, drawn uniformly by ``rng``; returns the new state and the mean loss. The
        statistics are left as they are (see :meth:`with_statistics`)."""
        data = {"obs": obs, "acts": acts, "next_obs": next_obs}
        what = "the inverse model's loss"
        return fused_fit(self.update, state, data, rng, n_steps, self.batch_size, self.chunk, what)
