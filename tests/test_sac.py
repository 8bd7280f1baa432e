"""SAC: hand-computed pieces of the losses, one update's bookkeeping, learning and determinism."""

from __future__ import annotations

from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rankgame.envs.make import make_env
from rankgame.envs.rollout import episode_returns, random_policy
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import SAC, SACConfig, sac_preset, squashed_gaussian_sample


def test_squashed_gaussian_logp_at_the_mean_is_the_normal_density() -> None:
    # u = 0: tanh'(0) = 1, so log p = sum_i log N(0; 0, 1) = -0.5 log(2 pi) per dimension.
    acts, logp = squashed_gaussian_sample(jnp.zeros((1, 3)), jnp.zeros((1, 3)), jnp.zeros((1, 3)))
    np.testing.assert_allclose(acts, 0.0)
    np.testing.assert_allclose(logp, [-1.5 * np.log(2 * np.pi)], rtol=1e-6)


def test_squashed_gaussian_logp_includes_the_tanh_jacobian() -> None:
    mean, log_std, noise = jnp.array([[0.3]]), jnp.array([[np.log(0.5)]]), jnp.array([[1.2]])
    u = 0.3 + 0.5 * 1.2
    expected = -0.5 * 1.2**2 - np.log(0.5) - 0.5 * np.log(2 * np.pi) - np.log(1 - np.tanh(u) ** 2)
    acts, logp = squashed_gaussian_sample(mean, log_std, noise)
    np.testing.assert_allclose(acts, [[np.tanh(u)]], rtol=1e-6)
    np.testing.assert_allclose(logp, [expected], rtol=1e-5)


def _batch(n_updates: int, batch: int, obs_dim: int = 3, act_dim: int = 2, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "obs": rng.normal(size=(n_updates, batch, obs_dim)).astype(np.float32),
        "acts": rng.uniform(-1, 1, size=(n_updates, batch, act_dim)).astype(np.float32),
        "next_obs": rng.normal(size=(n_updates, batch, obs_dim)).astype(np.float32),
        "dones": (rng.uniform(size=(n_updates, batch)) < 0.1).astype(np.float32),
        "rews": rng.normal(size=(n_updates, batch)).astype(np.float32),
    }


def test_target_networks_follow_polyak_averaging() -> None:
    sac = SAC(3, 2, SACConfig(hidden_sizes=(8,), polyak=0.9))
    state = sac.init(jax.random.key(0))
    old_target = jax.tree.map(np.asarray, state.target_critic_params)
    new_state, _ = sac.update(state, _batch(1, 16), None)
    expected = jax.tree.map(lambda t, c: 0.9 * t + 0.1 * np.asarray(c), old_target, new_state.critic_params)
    jax.tree.map(
        lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-7), new_state.target_critic_params, expected
    )
    assert int(new_state.n_updates) == 1


def test_critic_regresses_to_the_reward_when_gamma_is_zero() -> None:
    # With gamma = 0 the Bellman target is the reward itself: Q(s, a) -> r(s, a) = obs[0] + acts[0].
    def reward_fn(_params: None, batch: dict) -> jax.Array:
        return batch["obs"][:, 0] + batch["acts"][:, 0]

    sac = SAC(3, 2, SACConfig(hidden_sizes=(32, 32), gamma=0.0, critic_lr=3e-3), reward_fn=reward_fn)
    state = sac.init(jax.random.key(1))
    batches = _batch(2000, 64, seed=3)
    state, metrics = sac.update(state, batches, None)
    test = _batch(1, 256, seed=4)
    q = sac.critic.apply(state.critic_params, test["obs"][0], test["acts"][0])
    target = test["obs"][0, :, 0] + test["acts"][0, :, 0]
    assert float(jnp.max(jnp.mean((q - target) ** 2, axis=1))) < 0.05


def _absorbing_batch(n_updates: int, batch: int, seed: int) -> dict[str, np.ndarray]:
    """Transitions from real states (flag 0) into the absorbing state (zeros, flag 1)."""
    data = _batch(n_updates, batch, seed=seed)
    data["obs"][..., -1] = 0.0
    data["next_obs"][:] = 0.0
    data["next_obs"][..., -1] = 1.0
    data["dones"][:] = 0.0
    return data


def _flag_reward(_params: None, batch: dict) -> jax.Array:
    # r = 2 on real states, -1 on the absorbing state.
    return 2.0 - 3.0 * batch["obs"][:, -1]


def test_absorbing_state_is_valued_in_closed_form() -> None:
    sac = SAC(3, 2, SACConfig(hidden_sizes=(8,), gamma=0.9), reward_fn=_flag_reward, absorbing=True)
    assert float(sac.absorbing_value(None)) == pytest.approx(-1.0 / (1.0 - 0.9))


def test_critic_learns_the_value_of_terminating() -> None:
    # Every transition ends in s_abs: Q(s, a) = r(s) + gamma r(s_abs) / (1 - gamma) = 2 - 9 = -7.
    cfg = SACConfig(hidden_sizes=(32, 32), gamma=0.9, critic_lr=3e-3)
    sac = SAC(3, 2, cfg, reward_fn=_flag_reward, absorbing=True)
    state, _ = sac.update(sac.init(jax.random.key(1)), _absorbing_batch(2000, 64, seed=3), None)
    test = _absorbing_batch(1, 256, seed=4)
    q = sac.critic.apply(state.critic_params, test["obs"][0], test["acts"][0])
    np.testing.assert_allclose(np.asarray(q), -7.0, atol=0.3)


def test_actor_ignores_rows_that_start_in_the_absorbing_state() -> None:
    sac = SAC(3, 2, SACConfig(hidden_sizes=(8,)), reward_fn=_flag_reward, absorbing=True)
    state = sac.init(jax.random.key(0))
    before = jax.tree.map(np.asarray, state.actor_params)
    loops = _absorbing_batch(3, 16, seed=5)
    loops["obs"] = loops["next_obs"].copy()  # s_abs -> s_abs only
    state, _ = sac.update(state, loops, None)
    jax.tree.map(np.testing.assert_array_equal, before, jax.tree.map(np.asarray, state.actor_params))


def test_learned_temperature_rises_when_entropy_is_below_target() -> None:
    cfg = SACConfig(hidden_sizes=(8,), learn_alpha=True, target_entropy=100.0, alpha_lr=0.1)
    sac = SAC(3, 2, cfg)
    state = sac.init(jax.random.key(0))
    state, _ = sac.update(state, _batch(5, 16), None)
    assert float(jnp.exp(state.log_alpha)) > cfg.init_alpha


def test_fixed_temperature_stays_fixed() -> None:
    sac = SAC(3, 2, SACConfig(hidden_sizes=(8,)))
    state, metrics = sac.update(sac.init(jax.random.key(0)), _batch(3, 16), None)
    assert float(metrics["losses/alpha"]) == pytest.approx(0.2)


def test_presets_differ_as_documented() -> None:
    paper, modern = sac_preset("paper"), sac_preset("modern")
    assert (paper.batch_size, paper.actor_lr, paper.polyak, paper.learn_alpha) == (100, 1e-3, 0.995, False)
    assert (modern.batch_size, modern.actor_lr, modern.learn_alpha) == (256, 3e-4, True)
    with pytest.raises(ValueError, match="unknown SAC preset"):
        sac_preset("fancy")


def test_invalid_config_is_rejected() -> None:
    with pytest.raises(ValueError, match="gamma"):
        SACConfig(gamma=1.5).validate()


def _train(cfg: SACConfig, steps: int, seed: int) -> tuple[SACLearner, list[float]]:
    learner = SACLearner(make_env("rankgame/PointGoal-v0"), cfg, seed=seed)
    losses = []
    for _ in range(steps):
        learner.env_step()
        metrics = learner.maybe_update()
        if metrics:
            losses.append(metrics["losses/critic"])
    return learner, losses


def test_sac_learns_the_toy_task_far_beyond_chance(tiny_sac: SACConfig) -> None:
    env = make_env("rankgame/PointGoal-v0")
    random_returns = episode_returns(env, random_policy(env, 0), 20, seed=500)
    learner, _ = _train(tiny_sac, 1500, seed=0)
    returns = episode_returns(env, learner.policy(), 20, seed=500)
    # Random actions score about -24 and doing nothing about -32; the optimum is about -0.8.
    assert random_returns.mean() < -15
    assert returns.mean() > -5, returns.mean()


def test_same_seed_gives_identical_numbers(tiny_sac: SACConfig) -> None:
    first, losses_a = _train(tiny_sac, 600, seed=7)
    second, losses_b = _train(tiny_sac, 600, seed=7)
    other, losses_c = _train(tiny_sac, 600, seed=8)
    assert losses_a == losses_b and len(losses_a) > 0
    assert losses_a != losses_c
    env = make_env("rankgame/PointGoal-v0")
    np.testing.assert_array_equal(
        episode_returns(env, first.policy(), 3, seed=0), episode_returns(env, second.policy(), 3, seed=0)
    )


def test_a_terminal_step_is_stored_as_an_absorbing_transition(tiny_sac: SACConfig) -> None:
    """s -> s_abs, then the self-loop s_abs -> s_abs, neither with a terminal mask."""
    cfg = replace(tiny_sac, start_steps=10_000)  # uniformly random actions: steps off the ledge quickly
    env = make_env("rankgame/PointGoalEdge-v0")
    learner = SACLearner(env, cfg, seed=0, absorbing=True)
    while not learner.env_step().terminated:
        pass
    rows = {name: values[: learner.buffer.size] for name, values in learner.buffer.data.items()}
    flags_in, flags_out = rows["obs"][:, -1], rows["next_obs"][:, -1]
    assert learner.buffer.size == learner.env_steps + 1  # the self-loop row
    np.testing.assert_array_equal(flags_out[-2:], [1.0, 1.0])
    np.testing.assert_array_equal(flags_in[-2:], [0.0, 1.0])
    assert not rows["dones"].any()
