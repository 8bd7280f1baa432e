"""PPO: hand-computed GAE and surrogate, the absorbing bootstrap, learning, exact resume and saved actors."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rankgame.absorbing import absorbing_obs
from rankgame.checkpoint import flatten_tree, load_checkpoint, save_checkpoint
from rankgame.envs.make import make_env
from rankgame.envs.rollout import episode_returns, random_policy
from rankgame.envs.toy import POINT_GOAL_EDGE_ID, POINT_GOAL_ID
from rankgame.errors import NonFiniteError
from rankgame.policy.io import load_policy
from rankgame.policy.ppo import PPO, PPOConfig, clipped_surrogate, gae
from rankgame.policy.ppo_learner import PPOLearner
from rankgame.policy.sac import SAC, SACConfig

#: A small PPO that compiles quickly, for the tests that do not learn.
TINY = PPOConfig(hidden_sizes=(16, 16), rollout_steps=128, minibatch_size=32, epochs=2)


def test_gae_by_hand_with_a_time_limit_and_a_termination() -> None:
    # Step 0 ends at a time limit (bootstrapped with V(next_obs) = 5), step 1 continues into step 2,
    # which terminates (nothing after it). gamma = 0.9, lambda = 0.5, so gamma lambda = 0.45.
    rews = jnp.array([1.0, 2.0, 3.0])
    values = jnp.array([10.0, 20.0, 30.0])
    next_values = jnp.array([5.0, 30.0, 0.0])
    ends = jnp.array([1.0, 0.0, 1.0])
    # deltas: 1 + 0.9 * 5 - 10 = -4.5;  2 + 0.9 * 30 - 20 = 9;  3 + 0 - 30 = -27.
    # A_2 = -27;  A_1 = 9 + 0.45 * (-27) = -3.15;  A_0 = -4.5 (the time limit cuts the recursion).
    np.testing.assert_allclose(gae(rews, values, next_values, ends, 0.9, 0.5), [-4.5, -3.15, -27.0], rtol=1e-6)
    # Without the cut after step 0: A_0 = -4.5 + 0.45 * (-3.15) = -5.9175.
    no_cut = gae(rews, values, next_values, jnp.array([0.0, 0.0, 1.0]), 0.9, 0.5)
    np.testing.assert_allclose(no_cut, [-5.9175, -3.15, -27.0], rtol=1e-6)


def _rollout(ppo: PPO, steps: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    pre_tanh = rng.normal(size=(steps, ppo.act_dim)).astype(np.float32)
    return {
        "obs": rng.normal(size=(steps, ppo.obs_dim)).astype(np.float32),
        "acts": np.tanh(pre_tanh),
        "pre_tanh": pre_tanh,
        "logp": np.zeros(steps, np.float32),
        "next_obs": rng.normal(size=(steps, ppo.obs_dim)).astype(np.float32),
        "dones": np.zeros(steps, np.float32),
        "truncs": np.zeros(steps, np.float32),
        "rews": rng.normal(size=steps).astype(np.float32),
    }


def test_gae_inputs_bootstrap_with_the_critic_after_a_time_limit_and_with_zero_after_a_termination() -> None:
    ppo = PPO(2, 1, PPOConfig(hidden_sizes=(8,), rollout_steps=3, minibatch_size=3))
    state = ppo.init(jax.random.key(0))
    rollout = _rollout(ppo, 3)
    rollout["truncs"][0] = 1.0
    rollout["dones"][2] = 1.0
    inputs = ppo.gae_inputs(state, rollout, None)
    critic_next = np.asarray(ppo.critic.apply(state.critic_params, rollout["next_obs"]))
    np.testing.assert_allclose(inputs["next_values"], [critic_next[0], critic_next[1], 0.0], rtol=1e-6)
    np.testing.assert_array_equal(inputs["ends"], [1.0, 0.0, 1.0])
    np.testing.assert_array_equal(inputs["rews"], rollout["rews"])  # env_reward by default


def test_clipped_surrogate_by_hand() -> None:
    # ratios 1.5, 1.5, 1.1 (old log-probabilities 0), advantages +1, -1, +1, clip 0.2:
    # min(1.5, 1.2) = 1.2 (clipped: no gradient);  min(-1.5, -1.2) = -1.5;  min(1.1, 1.1) = 1.1.
    logp = jnp.log(jnp.array([1.5, 1.5, 1.1]))
    old, advantages = jnp.zeros(3), jnp.array([1.0, -1.0, 1.0])
    loss, grad = jax.value_and_grad(clipped_surrogate)(logp, old, advantages, 0.2)
    assert float(loss) == pytest.approx(-(1.2 - 1.5 + 1.1) / 3, rel=1e-6)
    # d/dlogp of -mean(rho A) is -rho A / 3 where unclipped.
    np.testing.assert_allclose(grad, [0.0, 1.5 / 3, -1.1 / 3], rtol=1e-5, atol=1e-7)


def _constant_reward(_params: None, batch: dict) -> jax.Array:
    return jnp.full(batch["obs"].shape[0], 0.7)


@pytest.mark.parametrize("absorbing", [True, False])
def test_the_value_after_a_termination_is_the_absorbing_state_value(absorbing: bool) -> None:
    cfg = PPOConfig(hidden_sizes=(8,), rollout_steps=1024, minibatch_size=64, gamma=0.9)
    learner = PPOLearner(make_env(POINT_GOAL_EDGE_ID), cfg, seed=0, reward_fn=_constant_reward, absorbing=absorbing)
    while not learner.env_step().terminated:  # the untrained policy walks off the ledge now and then
        assert learner.rollout_pos < cfg.rollout_steps
    last = learner.rollout_pos - 1
    assert learner.rollout["dones"][last] == 1.0
    inputs = learner.ppo.gae_inputs(learner.state, learner.rollout, None)
    if absorbing:  # s -> s_abs, then r(s_abs) = 0.7 forever: 0.7 / (1 - 0.9) = 7.
        np.testing.assert_array_equal(learner.rollout["next_obs"][last], absorbing_obs(2))
        assert float(inputs["next_values"][last]) == pytest.approx(0.7 / (1.0 - 0.9), rel=1e-6)
    else:
        assert float(inputs["next_values"][last]) == 0.0
    assert float(inputs["ends"][last]) == 1.0


def test_ppo_learns_the_toy_task_far_beyond_chance() -> None:
    env = make_env(POINT_GOAL_ID)
    n = 20
    random_returns = episode_returns(env, random_policy(env, 0), n, seed=500)
    learner = PPOLearner(make_env(POINT_GOAL_ID), PPOConfig(rollout_steps=256), seed=0)
    metrics = []
    for _ in range(12 * 256):
        learner.env_step()
        metrics.append(learner.maybe_update())
    updates = [m for m in metrics if m is not None]
    assert len(updates) == 12 and int(learner.state.n_updates) == 12
    expected = {"actor", "critic", "entropy", "approx_kl", "clip_fraction"}
    assert {f"losses/{name}" for name in expected} <= updates[-1].keys()
    assert all(np.isfinite(v) for m in updates for v in m.values())
    returns = episode_returns(env, learner.policy(), n, seed=500)  # the same starts as the random episodes
    # Random actions score about -26 with a spread of about 16 per episode (a standard error of the
    # mean of 20 episodes of about 3.6); the optimum is about -0.8. Require 5 standard errors.
    margin = 5.0 * random_returns.std() / np.sqrt(n)
    assert random_returns.mean() < -15
    assert returns.mean() > random_returns.mean() + margin, (returns.mean(), random_returns.mean(), margin)
    assert returns.mean() > -6, returns.mean()


def _scaled_env_reward(scale: jax.Array, batch: dict) -> jax.Array:
    return scale * batch["rews"]


def _run(learner: PPOLearner, steps: int, reward_params: float = 1.0) -> list[dict[str, float]]:
    metrics = []
    for _ in range(steps):
        learner.env_step()
        if (m := learner.maybe_update(reward_params)) is not None:
            metrics.append(m)
    return metrics


def test_restore_mid_rollout_continues_exactly_like_an_uninterrupted_run(tmp_path: Path) -> None:
    """A restored learner and the original one, whose episode is cut at the same step with the same reset
    seed (restore abandons the episode in progress, as SACLearner's does), stay identical."""
    original = PPOLearner(make_env(POINT_GOAL_ID), TINY, seed=3, reward_fn=_scaled_env_reward)
    _run(original, 190)  # one update at 128, then 62 steps into the second rollout, mid-episode
    assert original.rollout_pos == 62
    metadata, arrays = original.checkpoint()
    save_checkpoint(tmp_path / "checkpoint.npz", {**metadata, "config": {}}, arrays)
    metadata, arrays = load_checkpoint(tmp_path / "checkpoint.npz")

    # Another seed: everything must come back from the checkpoint.
    restored = PPOLearner(make_env(POINT_GOAL_ID), TINY, seed=99, reward_fn=_scaled_env_reward)
    restored.restore(metadata, arrays, seed=42)
    original.switch_env(make_env(POINT_GOAL_ID), seed=42)  # the same cut, without a checkpoint
    assert restored.rollout["truncs"][61] == 1.0 and restored.env_steps == 190
    for name in original.rollout:
        np.testing.assert_array_equal(restored.rollout[name][:62], original.rollout[name][:62], err_msg=name)

    metrics_a, metrics_b = _run(original, 200), _run(restored, 200)  # updates at 256 and 384
    assert len(metrics_a) == 2 and metrics_a == metrics_b
    state_a, state_b = flatten_tree("ppo", original.state), flatten_tree("ppo", restored.state)
    assert state_a.keys() == state_b.keys()
    for name in state_a:
        np.testing.assert_array_equal(state_a[name], state_b[name], err_msg=name)
    # ... and differ from a learner that was not restored.
    fresh = flatten_tree("ppo", PPOLearner(make_env(POINT_GOAL_ID), TINY, seed=99).state)
    assert any(not np.array_equal(state_a[name], fresh[name]) for name in state_a)


@pytest.mark.parametrize("absorbing", [True, False])
def test_a_saved_ppo_actor_loads_as_a_sac_actor_with_the_same_actions(tmp_path: Path, absorbing: bool) -> None:
    learner = PPOLearner(make_env(POINT_GOAL_ID), TINY, seed=1, absorbing=absorbing)
    obs_dim = learner.spec.obs_dim + int(absorbing)
    sac_actor = SAC(obs_dim, 1, SACConfig(hidden_sizes=TINY.hidden_sizes)).init(jax.random.key(0)).actor_params
    assert jax.tree.structure(sac_actor) == jax.tree.structure(learner.state.actor_params)
    assert jax.tree.map(np.shape, sac_actor) == jax.tree.map(np.shape, learner.state.actor_params)
    # SAC's initial actor (not scaled down like PPO's) acts far from 0: a stronger test of equal actions.
    learner.state = learner.state.replace(actor_params=sac_actor)

    path = learner.save_policy(tmp_path / "policy.msgpack", POINT_GOAL_ID, env_steps=learner.env_steps)
    saved = load_policy(path)
    assert saved.metadata["absorbing_flag"] is absorbing and saved.metadata["policy_player"] == "ppo"
    loaded, current = saved.policy_fn(deterministic=True), learner.policy(deterministic=True)
    for obs in np.random.default_rng(0).uniform(-1.5, 1.5, size=(10, 2)).astype(np.float32):
        np.testing.assert_array_equal(loaded(obs), current(obs))
    with pytest.raises(ValueError, match="absorbing_flag"):
        learner.save_policy(tmp_path / "other.msgpack", POINT_GOAL_ID, absorbing_flag=not absorbing)


def test_a_non_finite_loss_raises() -> None:
    learner = PPOLearner(make_env(POINT_GOAL_ID), TINY, seed=0, reward_fn=_scaled_env_reward)
    assert _run(learner, TINY.rollout_steps - 1, reward_params=float("nan")) == []
    learner.env_step()
    with pytest.raises(NonFiniteError, match="the PPO actor loss is not finite"):
        learner.maybe_update(float("nan"))


def test_invalid_config_is_rejected() -> None:
    with pytest.raises(ValueError, match="minibatch_size must divide rollout_steps"):
        PPOConfig(rollout_steps=100, minibatch_size=64).validate()
    with pytest.raises(ValueError, match="gamma"):
        PPOConfig(gamma=1.0).validate()
    with pytest.raises(ValueError, match="clip"):
        PPO(2, 1, PPOConfig(clip=0.0))
