"""f-IRL: the surrogate by hand, its gradient on a tabular problem, the density ratio of two known
distributions, learning the toy task, resume and the command line."""

from __future__ import annotations

import csv
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import assert_one_line_error, run_main

from rankgame import TrainConfig, train
from rankgame.envs.toy import POINT_GOAL_ID
from rankgame.game.rankings import RankingsConfig
from rankgame.reward.density_ratio import DensityRatio
from rankgame.reward.losses import H_FUNCTIONS, f_divergence_surrogate


def test_surrogate_is_the_covariance_of_summed_h_and_summed_reward_over_the_horizon() -> None:
    rewards = jnp.array([1.0, 2.0, 6.0, 0.0])
    h_sums = jnp.array([0.0, 2.0, 4.0, 100.0])
    weights = jnp.array([1.0, 1.0, 1.0, 0.0])  # the last row is padding
    # means 3 and 2; mean of products (0 + 4 + 24) / 3 = 28 / 3; covariance 28/3 - 6 = 10/3; over T = 5
    loss, metrics = f_divergence_surrogate(rewards, h_sums, weights, 5)
    np.testing.assert_allclose(loss, 10 / 3 / 5, rtol=1e-6)
    np.testing.assert_allclose(metrics["h_spread"], np.sqrt(8 / 3) / 5, rtol=1e-6)
    np.testing.assert_allclose(H_FUNCTIONS["rkl"](jnp.log(2.0)), -np.log(2.0))
    np.testing.assert_allclose(H_FUNCTIONS["fkl"](jnp.log(2.0)), -2.0)
    np.testing.assert_allclose(H_FUNCTIONS["js"](jnp.log(2.0)), -np.log(3.0), rtol=1e-6)


def _tabular_gradient(agent_visits: np.ndarray, expert_visits: np.ndarray, divergence: str) -> np.ndarray:
    """Gradient of the surrogate with respect to a tabular reward ``theta (S,)`` over one-hot states, for
    agent and expert trajectories given as state sequences ``(N, T)``, with the exact log ratio of the
    two state marginals."""
    n_states = int(max(agent_visits.max(), expert_visits.max())) + 1
    trajectories = np.concatenate([agent_visits, expert_visits])
    rho_agent = np.bincount(agent_visits.ravel(), minlength=n_states) / agent_visits.size
    rho_expert = np.bincount(expert_visits.ravel(), minlength=n_states) / expert_visits.size
    log_ratio = np.log(rho_expert + 1e-12) - np.log(rho_agent + 1e-12)
    h_sums = np.asarray(H_FUNCTIONS[divergence](jnp.asarray(log_ratio[trajectories]))).sum(axis=1)
    one_hot = np.eye(n_states, dtype=np.float32)[trajectories]  # (N, T, S)

    def loss(theta: jax.Array) -> jax.Array:
        rewards = jnp.sum(one_hot @ theta, axis=1)
        return f_divergence_surrogate(rewards, jnp.asarray(h_sums), jnp.ones(len(trajectories)), one_hot.shape[1])[0]

    return np.asarray(jax.grad(loss)(jnp.zeros(n_states)))


@pytest.mark.parametrize("divergence", ["fkl", "rkl", "js"])
def test_tabular_reward_gradient_vanishes_when_the_marginals_match_and_lowers_over_visited_states(
    divergence: str,
) -> None:
    rng = np.random.default_rng(0)
    expert = rng.integers(0, 4, (6, 20))
    same = rng.permuted(expert.ravel()).reshape(6, 20)  # the same state marginal, other trajectories
    np.testing.assert_allclose(_tabular_gradient(same, expert, divergence), 0.0, atol=1e-6)
    # The agent stays in state 0 more than the expert does and never reaches state 3.
    agent = np.where(rng.uniform(size=(6, 20)) < 0.5, 0, rng.integers(0, 3, (6, 20)))
    grad = _tabular_gradient(agent, expert, divergence)
    assert grad[0] > 0 and grad[3] < 0  # gradient descent lowers r(0) and raises r(3)


def test_density_ratio_recovers_the_log_ratio_of_two_gaussians() -> None:
    rng = np.random.default_rng(0)
    expert = rng.normal(1.0, 1.0, (20_000, 1)).astype(np.float32)
    agent = rng.normal(0.0, 1.0, (20_000, 1)).astype(np.float32)
    ratio = DensityRatio(1, hidden_sizes=(32, 32), lr=3e-3, weight_decay=0.0, batch_size=256)
    state, loss = ratio.fit(ratio.init(jax.random.key(0)), expert, agent, rng, 1500)
    x = np.linspace(-1.0, 2.0, 7, dtype=np.float32)[:, None]
    # log N(x; 1, 1) - log N(x; 0, 1) = x - 1/2
    np.testing.assert_allclose(ratio.log_ratio(state.params, x), x[:, 0] - 0.5, atol=0.2)
    assert loss < 2 * np.log(2)  # below chance (each side's mean cross-entropy is log 2 at chance)


def _config(out: Path, expert: Path, steps: int, resume: bool = False) -> TrainConfig:
    return TrainConfig(
        env=POINT_GOAL_ID,
        method="f-irl",
        expert=expert,
        expert_trajectories=10,
        steps=steps,
        eval_every=1000,
        eval_episodes=10,
        seed=1,
        out=out,
        resume=resume,
        tensorboard=False,
        progress=False,
        rankings=RankingsConfig(ratio_steps=100),
    )


def test_f_irl_learns_the_toy_task_and_resumes(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "firl"
    train(_config(out, toy_expert_file, 1000))
    summary = train(_config(out, toy_expert_file, 2000, resume=True))
    with (out / "metrics.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [row["env_steps"] for row in rows] == ["1000", "2000"]
    assert float(rows[-1]["reward/ratio_loss"]) < 2 * np.log(2)
    # Random actions score 0 and the expert 100; seeds 0 and 1 measured 96-100 from 2000 steps on.
    assert summary["normalized_score"] > 80, summary


def test_f_irl_refuses_what_it_cannot_use(
    capsys: pytest.CaptureFixture[str], toy_expert_file: Path, tmp_path: Path
) -> None:
    base = ["train", "--env", POINT_GOAL_ID, "--expert", str(toy_expert_file), "--no-progress", "--out"]
    base.append(str(tmp_path / "refused"))
    refusals = {
        ("--method", "f-irl", "--setting", "lfd"): "f-irl learns only from observations (lfo)",
        ("--method", "f-irl", "--rankings.k", "2"): "--rankings.k is not used by f-irl",
        (
            "--method",
            "rank-pal-auto",
            "--rankings.divergence",
            "js",
        ): "--rankings.divergence is not used by rank-pal-auto",
        ("--method", "f-irl", "--rankings.ratio-steps", "0"): "rankings ratio_steps must be positive",
    }
    for options, message in refusals.items():
        assert_one_line_error(run_main(capsys, *base, *options), message)
        assert not (tmp_path / "refused").exists()
