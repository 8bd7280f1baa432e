"""Absorbing states (Kostrikov et al., 2019, DAC), in one place for both players.

An episode that terminated after ``T < H`` steps is extended with the absorbing state ``s_abs``: every
observation the game handles carries one extra entry, the *absorbing flag*, last (0 for a real
state, 1 for ``s_abs``, whose other entries are all zero). The ranking data pads such an episode
with ``s_abs`` to the horizon, and the SAC buffer stores the matching transitions
(``s_{T-1} -> s_abs``, then the self-loop ``s_abs -> s_abs``, neither with a terminal mask), so the
reward learned for ``s_abs`` is exactly what the policy collects for ending an episode: early
termination is neither free nor a trap, whatever the sign of the learned reward. SAC values
``s_abs`` in closed form, ``r(s_abs) / (1 - gamma)``, instead of bootstrapping its self-loop (see
:class:`rankgame.policy.sac.SAC`).

Layout of a flagged observation: ``[obs (obs_dim,), flag ()]``, ``obs_dim + 1`` entries.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np


def flag_obs(obs: np.ndarray) -> np.ndarray:
    """Append a zero absorbing flag: ``(..., obs_dim) -> (..., obs_dim + 1)``."""
    return np.concatenate([obs, np.zeros((*obs.shape[:-1], 1), obs.dtype)], axis=-1)


def absorbing_obs(obs_dim: int) -> np.ndarray:
    """The absorbing state ``(obs_dim + 1,)``: zeros with the flag set."""
    state = np.zeros(obs_dim + 1, np.float32)
    state[-1] = 1.0
    return state


def absorbing_value(
    reward_fn: Callable[[Any, dict[str, jax.Array]], jax.Array],
    reward_params: Any,
    flagged_obs_dim: int,
    act_dim: int,
    gamma: float,
) -> jax.Array:
    """Value ``()`` of the absorbing state under ``reward_fn``, ``r(s_abs) / (1 - gamma)``: it loops on
    itself forever. ``flagged_obs_dim`` counts the flag; the self-loop's action is zeros ``(1, act_dim)``."""
    s_abs = jnp.asarray(absorbing_obs(flagged_obs_dim - 1))[None]
    zeros = jnp.zeros(1)
    loop = {"obs": s_abs, "next_obs": s_abs, "acts": jnp.zeros((1, act_dim)), "dones": zeros, "rews": zeros}
    return reward_fn(reward_params, loop)[0] / (1.0 - gamma)


def weighted_mean(values: jax.Array, weights: jax.Array) -> jax.Array:
    """Mean of ``values (..., B)`` over the last axis weighted by ``weights (B,)``, 0 when every weight is 0
    (how the players leave absorbing rows out of their expectations)."""
    return jnp.sum(values * weights, axis=-1) / jnp.maximum(jnp.sum(weights), 1e-8)


def absorbing_flag(flagged: np.ndarray | jax.Array) -> np.ndarray | jax.Array:
    """The flags ``(...)`` of flagged observations ``(..., obs_dim + 1)``: 1.0 for ``s_abs``, else 0.0."""
    return flagged[..., -1]


def padded_states(obs: np.ndarray, terminated: bool, horizon: int) -> np.ndarray:
    """Flagged states ``P[0..H]`` ``(H + 1, obs_dim + 1)`` float32 of one episode: its real states up to
    the last one acted in (and the final one after a time limit), then ``s_abs``.

    Args:
        obs: ``(T + 1, obs_dim)`` observations without flag; an episode longer than H is cut to H steps.
        terminated: whether the episode ended in a true terminal state (else a time limit).
        horizon: H.
    Raises:
        ValueError: an episode cut by a time limit before H steps (it cannot be aligned).
    """
    length = min(len(obs) - 1, horizon)
    if not terminated and length < horizon:
        raise ValueError(f"an episode cut by a time limit after {length} < {horizon} steps cannot be aligned")
    padded = np.tile(absorbing_obs(obs.shape[1]), (horizon + 1, 1))
    n_real = length if terminated else length + 1
    padded[:n_real] = flag_obs(obs[:n_real].astype(np.float32))
    return padded
