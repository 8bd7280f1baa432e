"""A density-ratio estimator: a classifier of expert against agent inputs whose logit estimates
``log rho_E(x) / rho_pi(x)`` (the classifier of f-IRL, Ni et al. 2020).

The optimal classifier of the balanced logistic loss is ``D* = rho_E / (rho_E + rho_pi)``, so its logit
``log D* - log(1 - D*)`` is the log density ratio (:func:`~rankgame.reward.losses.logistic_loss`). The
settings are those of the f-IRL authors' MuJoCo configurations: batches of 800 expert and 800 agent
inputs drawn with replacement, Adam 3e-4 with L2 weight decay 1e-4, the logit clipped to ``[-10, 10]``;
the network is a ReLU MLP of two hidden layers of 128 (theirs: residual tanh blocks of the same width).
The classifier is kept from one fit to the next, as theirs is.
"""

from __future__ import annotations

from typing import Any

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax

from rankgame.nets import MLP
from rankgame.reward.losses import logistic_loss

#: Gradient steps fused into one jitted call (their batches are sampled on the host, so this bounds memory).
STEPS_PER_CALL = 100

#: Bound on the estimated log ratio, as the f-IRL authors clip their classifier's logit.
LOG_RATIO_BOUND = 10.0


@flax.struct.dataclass
class RatioState:
    """The classifier's parameters and Adam state."""

    params: Any
    opt_state: Any


class DensityRatio:
    """Logistic classifier of expert (label 1) against agent (label 0) inputs ``(N, d)``.

    Args:
        dim: size of one input.
        hidden_sizes: hidden layer widths (ReLU).
        lr: Adam learning rate.
        weight_decay: L2 coefficient added to the gradient.
        batch_size: inputs of each side per gradient step.
    """

    def __init__(
        self,
        dim: int,
        hidden_sizes: tuple[int, ...] = (128, 128),
        lr: float = 3e-4,
        weight_decay: float = 1e-4,
        batch_size: int = 800,
    ) -> None:
        self.dim, self.batch_size = dim, batch_size
        self.net = MLP(hidden_sizes, 1)
        self.tx = optax.chain(optax.add_decayed_weights(weight_decay), optax.adam(lr))
        self._fit = jax.jit(self._fit_many, donate_argnums=(0,))
        self.log_ratio = jax.jit(self._log_ratio)

    def init(self, key: jax.Array) -> RatioState:
        params = self.net.init(key, jnp.zeros((1, self.dim), jnp.float32))
        return RatioState(params, self.tx.init(params))

    def _log_ratio(self, params: Any, inputs: jax.Array) -> jax.Array:
        """Estimated ``log rho_E / rho_pi`` ``(...)`` of inputs ``(..., d)``, clipped to the bound."""
        return jnp.clip(self.net.apply(params, inputs)[..., 0], -LOG_RATIO_BOUND, LOG_RATIO_BOUND)

    def _fit_many(self, state: RatioState, expert: jax.Array, agent: jax.Array) -> tuple[RatioState, jax.Array]:
        """Gradient steps over stacked batches ``(n, B, d)`` of each side; the mean loss."""
        labels = jnp.concatenate([jnp.ones(expert.shape[1]), jnp.zeros(agent.shape[1])])

        def step(carry: RatioState, batch: tuple[jax.Array, jax.Array]) -> tuple[RatioState, jax.Array]:
            inputs = jnp.concatenate(batch)

            def loss_fn(params: Any) -> jax.Array:
                return logistic_loss(self.net.apply(params, inputs)[:, 0], labels)[0]

            loss, grads = jax.value_and_grad(loss_fn)(carry.params)
            updates, opt_state = self.tx.update(grads, carry.opt_state, carry.params)
            return RatioState(optax.apply_updates(carry.params, updates), opt_state), loss

        state, losses = jax.lax.scan(step, state, (expert, agent))
        return state, jnp.mean(losses)

    def fit(
        self, state: RatioState, expert: np.ndarray, agent: np.ndarray, rng: np.random.Generator, steps: int
    ) -> tuple[RatioState, float]:
        """``steps`` gradient steps on batches drawn with replacement from ``expert (N, d)`` and
        ``agent (M, d)``; the new state and the mean loss."""
        losses = []
        for start in range(0, steps, STEPS_PER_CALL):
            n = min(STEPS_PER_CALL, steps - start)
            expert_idx = rng.integers(0, len(expert), size=(n, self.batch_size))
            agent_idx = rng.integers(0, len(agent), size=(n, self.batch_size))
            state, loss = self._fit(state, jnp.asarray(expert[expert_idx]), jnp.asarray(agent[agent_idx]))
            losses.append(float(loss) * n)
        return state, sum(losses) / steps
