"""Trajectories as time-aligned reward-input matrices, padded with absorbing states (App. B.1, C).

Mixup between agent and expert needs trajectories of equal length H. An episode that terminated
after T < H steps is extended DAC-style (Kostrikov et al., 2019): after its last real state comes
the absorbing state ``s_abs`` (all zeros with the absorbing flag set to 1) for the remaining steps,
with a zero action. The SAC buffer stores the same transitions (``s_{T-1} -> s_abs``, then
``s_abs -> s_abs`` without a terminal mask), so the reward the ranking game learns for ``s_abs`` is
exactly the reward the policy collects for terminating: early termination is neither free nor a
trap, whatever the sign of the learned reward. SAC values the absorbing state at exactly
``r(s_abs) / (1 - gamma)`` rather than bootstrapping its critic there (see
:class:`rankgame.policy.sac.SAC`): a bootstrapped self-loop drifts towards the value of the real
states and makes terminating look as good as surviving.

Observation layout used everywhere in the game: ``[obs, flag]`` with ``flag`` 0 for real states.
"""

from __future__ import annotations

import numpy as np

from rankgame.reward.nets import RewardInput


def flag_obs(obs: np.ndarray) -> np.ndarray:
    """Append a zero absorbing flag: ``(..., obs_dim) -> (..., obs_dim + 1)``."""
    return np.concatenate([obs, np.zeros((*obs.shape[:-1], 1), obs.dtype)], axis=-1)


def absorbing_obs(obs_dim: int) -> np.ndarray:
    """The absorbing state ``(obs_dim + 1,)``: zeros with the flag set."""
    state = np.zeros(obs_dim + 1, np.float32)
    state[-1] = 1.0
    return state


def trajectory_features(
    obs: np.ndarray,
    acts_norm: np.ndarray,
    terminated: bool,
    horizon: int,
    reward_input: RewardInput,
) -> np.ndarray:
    """Reward inputs of one episode, padded to the horizon: ``(horizon, d)`` float32.

    Args:
        obs: ``(T + 1, obs_dim)`` observations without flag.
        acts_norm: ``(T, act_dim)`` actions in the normalized box ``[-1, 1]``.
        terminated: whether the episode ended in a true terminal state (else a time limit).
        horizon: H; an episode longer than H is cut to its first H steps.
        reward_input: ``s``, ``ss`` or ``sa``.
    """
    length = min(len(acts_norm), horizon)
    obs_dim, act_dim = obs.shape[1], acts_norm.shape[1]
    # Padded states P[0..H]: real states up to the last one acted in, then absorbing.
    padded = np.tile(absorbing_obs(obs_dim), (horizon + 1, 1))
    n_real = length if terminated else length + 1
    padded[:n_real] = flag_obs(obs[:n_real].astype(np.float32))
    if not terminated and length < horizon:
        raise ValueError(f"an episode cut by a time limit after {length} < {horizon} steps cannot be aligned")
    if reward_input == "s":
        return padded[:horizon]
    if reward_input == "ss":
        return np.concatenate([padded[:horizon], padded[1:]], axis=-1)
    acts = np.zeros((horizon, act_dim), np.float32)
    acts[:length] = acts_norm[:length]
    return np.concatenate([padded[:horizon], acts], axis=-1)
