"""Environment factory and rollouts."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from rankgame.envs.make import env_spec, make_env
from rankgame.envs.rollout import (
    evaluate_episodes,
    rollout,
    run_episodes,
    success_rate,
    to_env_action,
    to_normalized_action,
)
from rankgame.envs.toy import point_goal_expert
from rankgame.envs.variants import OBS_PREFIX_VARIANTS
from rankgame.errors import RankGameError


@pytest.mark.parametrize(
    ("env_id", "obs_dim", "act_dim"),
    [
        ("Hopper-v5", 11, 3),
        ("HalfCheetah-v5", 17, 6),
        ("Walker2d-v5", 17, 6),
        ("Ant-v5", 105, 8),
        ("Humanoid-v5", 348, 17),
        ("Swimmer-v5", 8, 2),
    ],
)
def test_locomotion_tasks(env_id: str, obs_dim: int, act_dim: int) -> None:
    spec = env_spec(make_env(env_id))
    assert (spec.obs_dim, spec.act_dim, spec.max_episode_steps) == (obs_dim, act_dim, 1000)


@pytest.mark.parametrize("variant_id", sorted(OBS_PREFIX_VARIANTS))
def test_variants_without_contact_forces_observe_the_leading_entries_of_their_task(variant_id: str) -> None:
    source_id, n_obs = OBS_PREFIX_VARIANTS[variant_id]
    variant, source = make_env(variant_id), make_env(source_id)
    assert env_spec(variant).obs_dim == n_obs
    assert env_spec(variant).max_episode_steps == env_spec(source).max_episode_steps
    obs_v, _ = variant.reset(seed=3)
    obs_s, _ = source.reset(seed=3)
    rng = np.random.default_rng(0)
    left_out = 0.0
    for _ in range(30):
        np.testing.assert_array_equal(obs_v, obs_s[:n_obs])
        act = rng.uniform(-0.4, 0.4, env_spec(source).act_dim)
        obs_v, rew_v, *_ = variant.step(act)
        obs_s, rew_s, *_ = source.step(act)
        assert rew_v == rew_s
        left_out = max(left_out, float(np.abs(obs_s[n_obs:]).max()))
    assert left_out > 0.0  # what the variant leaves out: contact forces, not zeros


def test_other_continuous_ids_work() -> None:
    assert env_spec(make_env("Pendulum-v1")).act_dim == 1


def test_unknown_and_discrete_envs_are_rejected() -> None:
    with pytest.raises(RankGameError, match="unknown environment id 'Hoper-v5'"):
        make_env("Hoper-v5")
    with pytest.raises(RankGameError, match="Discrete action space"):
        make_env("CartPole-v1")


def test_action_scaling_round_trip() -> None:
    low, high = np.array([-0.4, 0.0]), np.array([0.4, 2.0])
    np.testing.assert_allclose(to_env_action(np.array([-1.0, 1.0]), low, high), [-0.4, 2.0])
    acts = np.array([0.1, 1.5])
    np.testing.assert_allclose(to_env_action(to_normalized_action(acts, low, high), low, high), acts)


def test_rollout_records_whole_seeded_episodes() -> None:
    env = make_env("rankgame/PointGoal-v0")
    first = rollout(env, point_goal_expert, 2, seed=4)
    again = rollout(env, point_goal_expert, 2, seed=4)
    assert [len(t) for t in first] == [40, 40] and first[0].truncated[-1]
    np.testing.assert_array_equal(first[1].obs, again[1].obs)
    assert first[0].ret > -3.0


class _SucceedsForSeedSteps(gym.Env):
    """30-step episodes whose first ``seed`` steps report ``info["success"]``; reward 1 per step."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        self.t, self.successes = 0, int(seed or 0)
        return np.zeros(1, np.float32), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.t += 1
        return np.zeros(1, np.float32), 1.0, False, self.t == 30, {"success": self.t <= self.successes}


def test_success_counts_steps_and_an_episode_succeeds_above_twenty_of_them() -> None:
    episodes, success_steps = run_episodes(_SucceedsForSeedSteps(), lambda obs: np.zeros(1), 3, seed=19)
    assert [len(episode) for episode in episodes] == [30, 30, 30]
    assert success_steps == [19, 20, 21]
    assert success_rate(success_steps) == pytest.approx(1 / 3)  # only 21 > 20
    returns, rate = evaluate_episodes(_SucceedsForSeedSteps(), lambda obs: np.zeros(1), 2, seed=21)
    np.testing.assert_array_equal(returns, [30.0, 30.0])
    assert rate == 1.0
    assert success_rate([25, 0, 30, 3]) == 0.5


def test_tasks_without_success_have_no_success_rate() -> None:
    env = make_env("rankgame/PointGoal-v0")
    _, success_steps = run_episodes(env, point_goal_expert, 2, seed=0)
    assert success_steps == [None, None] and success_rate(success_steps) is None


def test_successful_episodes_keeps_the_first_that_succeed_and_gives_up_in_time() -> None:
    from rankgame.errors import RankGameError
    from rankgame.expert import MAX_TRIES_PER_EPISODE, successful_episodes

    policy = lambda obs: np.zeros(1)  # noqa: E731
    # Seeds 19 and 20 give 19 and 20 successful steps (not more than 20): skipped; 21 and 22 kept.
    kept, tries = successful_episodes(_SucceedsForSeedSteps(), policy, 2, seed=19)
    assert (len(kept), tries) == (2, 4)
    with pytest.raises(RankGameError, match=f"only 0 of {MAX_TRIES_PER_EPISODE} episodes succeeded"):
        successful_episodes(_SucceedsForSeedSteps(), policy, 1, seed=0)  # seeds 0-19: at most 19 steps
    with pytest.raises(RankGameError, match="reports no success"):
        successful_episodes(make_env("rankgame/PointGoal-v0"), point_goal_expert, 1, seed=0)
