"""The reward the policy player is paid: the reward player's latest, or the mean of its last few.

In the paper (Alg. 1) the policy player maximizes the reward player's latest reward. A game whose
players each respond to the other's latest move can cycle instead of settling; the classic remedy is
to respond to the opponent's *average* strategy (fictitious play). With a window of ``N`` iterations
the policy player is paid

    r_bar(x) = (1 / n) sum_{i < n} r_{t - i}(x),    n = min(N, number of rewards so far),

the mean of the bounded rewards ``r_t, r_{t-1}, ...`` the reward player held after its last ``n``
turns (one per iteration); before its first turn, the reward at initialization. ``N = 1`` is the paper's
method: the latest reward, the same function and parameters as before, bit for bit. Everything else
that reads the reward (the ranking losses, the logged ``reward/agent`` and ``reward/expert``, policy
selection, ``rankgame export-reward``) keeps reading the latest one.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np

from rankgame.checkpoint import flatten_tree, unflatten_tree

#: ``(reward_params, batch) -> rews (B,)``, as the policy players take it.
RewardFn = Callable[[Any, dict[str, jax.Array]], jax.Array]

#: Checkpoint prefix of the window's arrays.
CHECKPOINT_PREFIX = "policy_reward"


@flax.struct.dataclass
class RewardWindow:
    """The last rewards in a ring.

    Attributes:
        params: the reward parameters, every leaf stacked ``(N, ...)``; slot ``i % N`` holds the ``i``-th
            reward pushed, and slot 0 the one the window started from until a reward is pushed.
        count: ``()`` int32, rewards pushed so far; the first ``min(max(count, 1), N)`` slots are filled.
    """

    params: Any
    count: jax.Array


class RewardAverage:
    """Pays the policy player the mean of the last ``size`` rewards (see the module docstring).

    Args:
        reward_fn: the reward player's bounded reward ``(params, batch) -> (B,)``.
        size: the window ``N`` >= 1; 1 hands the latest reward's own function and parameters through.
    """

    def __init__(self, reward_fn: RewardFn, size: int) -> None:
        if size < 1:
            raise ValueError(f"the reward window must hold at least 1 reward, not {size}")
        self.size = size
        self.base_fn = reward_fn
        self.reward_fn: RewardFn = reward_fn if size == 1 else self._mean_reward
        self._push = jax.jit(self._push_one)

    def start(self, params: Any) -> Any:
        """The policy player's reward parameters when only ``params`` exist (at initialization, or after
        an expert switch): a window holding ``params`` alone until the first :meth:`push` replaces them,
        or ``params`` itself when ``size`` is 1."""
        if self.size == 1:
            return params
        stacked = jax.tree.map(lambda leaf: jnp.repeat(jnp.asarray(leaf)[None], self.size, axis=0), params)
        return RewardWindow(params=stacked, count=jnp.zeros((), jnp.int32))

    def push(self, window: Any, params: Any) -> Any:
        """``window`` with the reward player's new ``params`` added, the oldest dropped once it is full."""
        return params if self.size == 1 else self._push(window, params)

    def _push_one(self, window: RewardWindow, params: Any) -> RewardWindow:
        slot = window.count % self.size
        stacked = jax.tree.map(lambda ring, leaf: ring.at[slot].set(leaf), window.params, params)
        return RewardWindow(params=stacked, count=window.count + 1)

    def _mean_reward(self, window: RewardWindow, batch: dict[str, jax.Array]) -> jax.Array:
        """``r_bar`` ``(B,)`` of a batch: the filled slots' rewards ``(N, B)`` averaged over the slots."""
        rews = jax.vmap(lambda params: self.base_fn(params, batch))(window.params)
        filled = (jnp.arange(self.size) < jnp.maximum(window.count, 1)).astype(rews.dtype)
        return filled @ rews / jnp.sum(filled)

    def state_dict(self, window: Any) -> dict[str, np.ndarray]:
        """Checkpoint arrays of ``window`` (none when ``size`` is 1: it is the reward player's state)."""
        return {} if self.size == 1 else flatten_tree(CHECKPOINT_PREFIX, window)

    def load(self, arrays: dict[str, np.ndarray], window: Any, params: Any) -> Any:
        """Inverse of :meth:`state_dict`, ``window`` giving the structure; ``params`` are the restored
        reward player's (the window itself when ``size`` is 1)."""
        return params if self.size == 1 else unflatten_tree(CHECKPOINT_PREFIX, arrays, window)
