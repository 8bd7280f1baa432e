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


#: An episode succeeds when its task reports ``info["success"]`` at more than this many of its steps:
#: the rule of mjrl's pen-v0 evaluation (the pen held at the goal for more than 20 of its 100 steps).
SUCCESS_MIN_STEPS = 20


def run_episodes(
    env: gym.Env, policy: PolicyFn, n_episodes: int, seed: int
) -> tuple[list[Trajectory], list[int | None]]:
    """Record ``n_episodes`` full episodes; episode ``i`` starts from ``env.reset(seed=seed + i)``.

    Also returns, per episode, the number of steps at which the task reported ``info["success"]``
    (None for tasks that never report it, such as the locomotion tasks).
    """
    episodes, success_steps = [], []
    for i in range(n_episodes):
        obs, _ = env.reset(seed=seed + i)
        obs_list, acts, rews, terms, truncs = [obs], [], [], [], []
        successes: int | None = None
        done = False
        while not done:
            act = np.asarray(policy(obs), dtype=np.float32)
            obs, rew, terminated, truncated, info = env.step(act)
            if "success" in info:
                successes = (successes or 0) + bool(info["success"])
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
        success_steps.append(successes)
    return episodes, success_steps


def rollout(env: gym.Env, policy: PolicyFn, n_episodes: int, seed: int) -> list[Trajectory]:
    """The episodes of :func:`run_episodes` alone."""
    return run_episodes(env, policy, n_episodes, seed)[0]


def episode_succeeded(success_steps: int) -> bool:
    """Whether an episode whose task reported success at ``success_steps`` steps succeeded."""
    return success_steps > SUCCESS_MIN_STEPS


def success_rate(success_steps: list[int | None]) -> float | None:
    """Share of episodes (success counts from :func:`run_episodes`) that succeeded; None when the task
    reports no success."""
    if any(steps is None for steps in success_steps) or not success_steps:
        return None
    return float(np.mean([episode_succeeded(steps) for steps in success_steps]))


def success_postfix(success: float | None) -> dict[str, str]:
    """Progress-bar field of a success rate, ``{"success": "60%"}``; empty when the task reports none."""
    return {} if success is None else {"success": f"{success:.0%}"}


def evaluate_episodes(env: gym.Env, policy: PolicyFn, n_episodes: int, seed: int) -> tuple[np.ndarray, float | None]:
    """Undiscounted returns ``(n_episodes,)`` of ``policy`` and its :func:`success_rate` (seeding as in
    :func:`run_episodes`)."""
    episodes, success_steps = run_episodes(env, policy, n_episodes, seed)
    return np.array([episode.ret for episode in episodes]), success_rate(success_steps)


def episode_returns(env: gym.Env, policy: PolicyFn, n_episodes: int, seed: int) -> np.ndarray:
    """Undiscounted returns ``(n_episodes,)`` of ``policy`` (see :func:`run_episodes` for seeding)."""
    return evaluate_episodes(env, policy, n_episodes, seed)[0]


def random_policy(env: gym.Env, seed: int) -> PolicyFn:
    """Uniformly random actions over the action box, reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    low, high = env.action_space.low, env.action_space.high
    return lambda _obs: rng.uniform(low, high).astype(np.float32)
