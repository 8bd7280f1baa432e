"""Run a policy in an environment: recorded episodes and returns for evaluation and expert data."""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym
import numpy as np

from rankgame.data.trajectories import Trajectory

#: Maps one observation ``(obs_dim,)`` to one action ``(act_dim,)`` in environment units.
PolicyFn = Callable[[np.ndarray], np.ndarray]

#: Evaluation episodes of a run with seed ``s`` reset from ``s + EVAL_SEED_OFFSET + i``, apart from
#: the resets of its training episodes.
EVAL_SEED_OFFSET = 10_000


def to_env_action(acts: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Map normalized actions in ``[-1, 1]`` to the box ``[low, high]`` (any leading shape)."""
    return low + 0.5 * (acts + 1.0) * (high - low)


def to_normalized_action(acts: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_env_action`."""
    return 2.0 * (acts - low) / (high - low) - 1.0


def rollout(env: gym.Env, policy: PolicyFn, n_episodes: int, seed: int) -> list[Trajectory]:
    """Record ``n_episodes`` full episodes; episode ``i`` starts from ``env.reset(seed=seed + i)``."""
    episodes = []
    for i in range(n_episodes):
        obs, _ = env.reset(seed=seed + i)
        obs_list, acts, rews, terms, truncs = [obs], [], [], [], []
        done = False
        while not done:
            act = np.asarray(policy(obs), dtype=np.float32)
            obs, rew, terminated, truncated, _ = env.step(act)
            obs_list.append(obs)
            acts.append(act)
            rews.append(rew)
            terms.append(terminated)
            truncs.append(truncated)
            done = terminated or truncated
        episodes.append(
            Trajectory(
                obs=np.asarray(obs_list, np.float32),
                acts=np.asarray(acts, np.float32),
                rews=np.asarray(rews, np.float32),
                terminated=np.asarray(terms, bool),
                truncated=np.asarray(truncs, bool),
            )
        )
    return episodes


def episode_returns(env: gym.Env, policy: PolicyFn, n_episodes: int, seed: int) -> np.ndarray:
    """Undiscounted returns ``(n_episodes,)`` of ``policy`` (see :func:`rollout` for seeding)."""
    return np.array([episode.ret for episode in rollout(env, policy, n_episodes, seed)])


def random_policy(env: gym.Env, seed: int) -> PolicyFn:
    """Uniformly random actions over the action box, reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    low, high = env.action_space.low, env.action_space.high
    return lambda _obs: rng.uniform(low, high).astype(np.float32)
