"""The discriminator and T-REX pieces: losses against hand-computed values, the discriminator's known
optimum, snippet pairs, the simultaneous and reward-first leaders, and the methods' settings."""

from __future__ import annotations

import csv
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from conftest import TOY_PPO_ARGS, TOY_TRAIN_ARGS

from rankgame.cli import main
from rankgame.config import TrainConfig
from rankgame.errors import RankGameError
from rankgame.game.leaders import LeaderConfig, make_leader
from rankgame.game.methods import METHODS
from rankgame.game.rankings import PairwiseRankings, Rankings, RankingsConfig, build_rankings
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import (
    LOSSES,
    bound_reward,
    bradley_terry_loss,
    gradient_penalty,
    logistic_loss,
)
from rankgame.reward.offline_rankings import OfflineRankings
from rankgame.reward.player import RewardConfig, RewardPlayer


def test_logistic_loss_is_the_cross_entropy_of_each_side() -> None:
    # expert row: logit 0, -log sigmoid(0) = log 2; agent row: logit log 3, -log(1 - 3/4) = log 4.
    loss, metrics = logistic_loss(jnp.array([0.0, math.log(3.0)]), jnp.array([1.0, 0.0]))
    assert float(loss) == pytest.approx(math.log(8.0), rel=1e-6)
    assert float(metrics["accuracy"]) == pytest.approx(0.0)  # D = 1/2 on the expert row is not > 1/2
    assert float(metrics["expert_d"]) == pytest.approx(0.5)


def test_logistic_loss_weighs_each_side_by_its_own_mean() -> None:
    # Three agent rows at logit 0 count as much as one: log 2 + log 2.
    loss, _ = logistic_loss(jnp.zeros(4), jnp.array([1.0, 0.0, 0.0, 0.0]))
    assert float(loss) == pytest.approx(2 * math.log(2.0), rel=1e-6)


def test_the_fitted_discriminator_reaches_its_known_optimum_on_one_hot_states() -> None:
    """Tabular: D*(s) = rho_E(s) / (rho_E(s) + rho_pi(s)); states of one side only go to 1 or 0."""
    rho_e = np.array([0.5, 0.3, 0.2, 0.0])
    rho_pi = np.array([0.0, 0.6, 0.1, 0.3])
    states = jnp.eye(4)
    inputs = jnp.concatenate([states, states])
    is_expert = jnp.array([1.0] * 4 + [0.0] * 4)
    weights = jnp.asarray(np.concatenate([rho_e, rho_pi]), jnp.float32)

    def loss_fn(table: jax.Array) -> jax.Array:
        return logistic_loss(inputs @ table, is_expert, weights)[0]

    tx = optax.adam(0.1)

    def step(carry: tuple[jax.Array, optax.OptState], _: None) -> tuple[tuple[jax.Array, optax.OptState], None]:
        table, opt_state = carry
        updates, opt_state = tx.update(jax.grad(loss_fn)(table), opt_state)
        return (optax.apply_updates(table, updates), opt_state), None

    table = jnp.zeros(4)
    (table, _), _ = jax.jit(lambda c: jax.lax.scan(step, c, None, length=3000))((table, tx.init(table)))
    d = np.asarray(jax.nn.sigmoid(table))
    np.testing.assert_allclose(d[1:3], [0.3 / 0.9, 0.2 / 0.3], atol=2e-3)
    assert d[0] > 0.99 and d[3] < 0.01


def test_gradient_penalty_of_a_linear_discriminator_is_its_slope_minus_one_squared() -> None:
    w = jnp.array([1.2, -1.6])  # norm 2
    points = jnp.asarray(np.random.default_rng(0).normal(size=(5, 2)), jnp.float32)
    assert float(gradient_penalty(lambda x: x @ w, points)) == pytest.approx(1.0, rel=1e-5)
    assert float(gradient_penalty(lambda x: x @ (w / 2), points)) == pytest.approx(0.0, abs=1e-6)


def test_bradley_terry_loss_is_the_luce_shepard_log_likelihood() -> None:
    loss, metrics = bradley_terry_loss(jnp.array([1.0, 0.0]), jnp.array([0.0, 0.0]))
    # P = e / (e + 1) for the first pair, 1/2 for the second.
    expected = -(math.log(math.e / (math.e + 1)) + math.log(0.5)) / 2
    assert float(loss) == pytest.approx(expected, rel=1e-6)
    assert float(metrics["accuracy"]) == pytest.approx(0.5)


def test_discriminator_rewards_are_gails_and_dacs_forms() -> None:
    raw = jnp.array([0.0, 2.0, 50.0, -50.0])
    gail = bound_reward(raw, 10.0, LOSSES["logistic"].bound)  # -log(1 - sigmoid(x)), capped
    np.testing.assert_allclose(gail, [math.log(2.0), math.log(1 + math.e**2), 10.0, 0.0], atol=1e-6)
    dac = bound_reward(raw, 10.0, LOSSES["logistic-gp"].bound)  # log D - log(1 - D) = x, clipped
    np.testing.assert_allclose(dac, [0.0, 2.0, 10.0, -10.0])


def _chain(n_ranked: int = 3, horizon: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Offline trajectories whose every input holds its rank (entry 0) and time step (entry 1)."""
    t = np.arange(horizon, dtype=np.float32)
    ranked = np.stack([np.stack([np.full(horizon, i, np.float32), t], -1) for i in range(n_ranked)])
    expert = np.stack([np.full(horizon, n_ranked, np.float32), t], -1)[None]
    return ranked, expert


def test_snippet_pairs_compare_two_behaviors_and_the_better_one_starts_no_earlier() -> None:
    ranked, expert = _chain()
    chain = OfflineRankings(ranked, expert, np.linspace(0, 1, 4), snippet_length=5)
    better, worse = chain.sample_pairs(np.random.default_rng(0), 4, 64)
    assert better.shape == worse.shape == (4, 64, 5, 2)
    assert np.all(better[..., 0] > worse[..., 0])  # a different, better-ranked behavior
    assert np.all(better[..., 0, 1] >= worse[..., 0, 1])  # starts no earlier
    assert np.all(np.diff(better[..., 1], axis=-1) == 1)  # consecutive steps of one trajectory
    assert set(np.unique(better[..., 0])) == {1.0, 2.0, 3.0}  # the expert is the top of the chain


def test_offline_rankings_need_a_pairwise_loss_and_only_they_use_one() -> None:
    ranked, expert = _chain()
    layout = InputLayout(1, 1, "s")
    config = RankingsConfig(snippet_length=5)
    rankings = build_rankings("offline", config, expert, layout, 0.1, LOSSES["bradley-terry"], ranked)
    assert isinstance(rankings, PairwiseRankings)
    with pytest.raises(ValueError, match="pairwise"):
        build_rankings("offline", config, expert, layout, 0.1, LOSSES["regression"], ranked)
    with pytest.raises(ValueError, match="pairwise"):
        build_rankings("vanilla", config, expert, layout, 0.1, LOSSES["bradley-terry"])
    with pytest.raises(ValueError, match="need preference data"):
        build_rankings("offline", config, expert, layout, 0.1, LOSSES["bradley-terry"])


def test_trex_reward_orders_the_chain_after_its_opening_fit() -> None:
    """Entry 0 of every input is its behavior's rank: the fitted reward must increase along it."""
    ranked, expert = _chain(n_ranked=4)
    layout = InputLayout(1, 1, "s")
    rankings = build_rankings(
        "offline", RankingsConfig(snippet_length=5), expert, layout, 0.1, LOSSES["bradley-terry"], ranked
    )
    player = RewardPlayer(layout, LOSSES["bradley-terry"], RewardConfig(hidden_sizes=(16,), batch_size=200), rankings)
    leader = make_leader("reward-first", LeaderConfig(opening_steps=400))
    rng = np.random.default_rng(0)
    state, metrics = leader.opening(player, player.init(jax.random.key(0)), rng)
    assert metrics["reward/accuracy"] > 0.9
    ranks = np.arange(5, dtype=np.float32)
    rewards = np.asarray(player.net.apply(state.params, jnp.stack([ranks, np.full(5, 10.0)], -1)))
    assert np.all(np.diff(rewards) > 0), rewards
    # It never moves again, and never sees agent data.
    agent = np.zeros((1, 20, 2), np.float32)
    leader.receive(rankings, list(agent), rng)
    assert rankings.data.n_trajectories == 0 and leader.fit(player, state, rng) is None


def test_the_gradient_penalty_flattens_a_steep_discriminator() -> None:
    """One-hot-like 1-D inputs: without the penalty the logit's slope grows; with it it stays near 1."""
    expert = np.full((1, 10, 2), [1.0, 0.0], np.float32)
    agent = [np.full((10, 2), [-1.0, 0.0], np.float32)]
    layout = InputLayout(1, 1, "s")
    slopes = {}
    for name in ("logistic", "logistic-gp"):
        rankings = build_rankings("vanilla", RankingsConfig(), expert, layout, 0.0, LOSSES[name])
        assert isinstance(rankings, Rankings) and rankings.penalty_points == (name == "logistic-gp")
        rankings.data.add(agent, np.random.default_rng(0))
        player = RewardPlayer(layout, LOSSES[name], RewardConfig(hidden_sizes=(16,), batch_size=64), rankings)
        state, _, metrics = player.fit_steps(player.init(jax.random.key(1)), 800, np.random.default_rng(1))
        grid = jnp.stack([jnp.linspace(-1, 1, 21), jnp.zeros(21)], -1)
        slopes[name] = float(jnp.max(jnp.abs(jnp.diff(player.net.apply(state.params, grid)))) / 0.1)
        assert ("reward/gradient_penalty" in metrics) == (name == "logistic-gp")
    assert slopes["logistic-gp"] < 1.5 < slopes["logistic"], slopes


@pytest.mark.parametrize(
    ("leader", "gda_steps", "expected"), [("gda", None, 25), ("gda-replay", None, 12), ("gda", 7, 7)]
)
def test_simultaneous_leaders_take_a_fixed_number_of_steps(leader: str, gda_steps: int | None, expected: int) -> None:
    """gda: five passes over the iteration's rows, half of each batch (ceil(5 * 2 * 120 / 48) = 25);
    gda-replay: n_pol / 10."""
    expert = np.ones((1, 20, 2), np.float32)
    layout = InputLayout(1, 1, "s")
    rankings = build_rankings("vanilla", RankingsConfig(), expert, layout, 0.0, LOSSES["logistic"])
    player = RewardPlayer(layout, LOSSES["logistic"], RewardConfig(hidden_sizes=(8,), batch_size=48), rankings)
    calls: list[int] = []
    fit_steps = player.fit_steps
    player.fit_steps = lambda state, n, rng: (calls.append(n), fit_steps(state, n, rng))[1]  # type: ignore[method-assign]
    policy = make_leader(leader, LeaderConfig(gda_steps=gda_steps), policy_updates=120)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    state = player.init(jax.random.key(0))
    for _ in range(2):
        policy.receive(rankings, [np.zeros((20, 2), np.float32)] * 6, rng)
        state, _ = policy.fit(player, state, rng)  # type: ignore[misc]
    assert calls == [expected, expected]
    assert rankings.data.n_trajectories == (12 if leader == "gda-replay" else 6)  # the whole buffer, or the last


def test_each_method_states_its_setting_and_input() -> None:
    assert TrainConfig(method="gail").resolved_setting == "lfd"
    assert TrainConfig(method="dac").resolved_reward_input == "sa"
    assert TrainConfig(method="dacfo").resolved_reward_input == "ss"
    assert TrainConfig(method="gaifo").resolved_reward_input == "ss"
    assert TrainConfig(method="trex").resolved_reward_input == "s"
    assert all(method.settings for method in METHODS.values())


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"method": "gail", "setting": "lfo"}, "gail learns only from demonstrations (lfd), not with --setting lfo"),
        ({"method": "dacfo", "setting": "lfd"}, "dacfo learns only from observations (lfo)"),
        ({"method": "dac", "leader": LeaderConfig(patience=2)}, "--leader.patience is not used by dac"),
        ({"method": "rank-pal-auto", "leader": LeaderConfig(gda_steps=5)}, "--leader.gda-steps is not used by"),
        ({"method": "rank-pal-auto", "reward": RewardConfig(gradient_penalty=1.0)}, "--reward.gradient-penalty"),
        ({"method": "trex", "rankings": RankingsConfig(k=2.0)}, "--rankings.k is not used by trex"),
        ({"method": "trex", "reward": RewardConfig(policy_window=3)}, "--reward.policy-window is not used by trex"),
        (
            {"method": "dacfo", "reward": RewardConfig(ranking_gradient_penalty=1.0)},
            "--reward.ranking-gradient-penalty is not used by dacfo",
        ),
    ],
)
def test_an_option_or_setting_a_method_cannot_use_is_refused(options: dict, message: str) -> None:
    with pytest.raises(RankGameError, match=re.escape(message)):
        TrainConfig(**options).validate()


def _read_rows(out: Path) -> list[dict[str, str]]:
    if not (out / "metrics.csv").exists():
        return []
    with (out / "metrics.csv").open() as handle:
        return list(csv.DictReader(handle))


def _train_rows(args: list[str], out: Path) -> list[dict[str, str]]:
    assert main(["train", *args, "--eval-every", "1000", "--eval-episodes", "10", "--out", str(out)]) == 0
    return _read_rows(out)


@pytest.mark.parametrize("method", ["dac", "dacfo"])
def test_dac_and_dacfo_imitate_the_analytic_expert(method: str, toy_expert_file: Path, tmp_path: Path) -> None:
    args = [*TOY_TRAIN_ARGS, "--method", method, "--expert", str(toy_expert_file), "--steps", "2000"]
    rows = _train_rows(args, tmp_path / method)
    # 0 is a uniformly random policy, 100 the expert; the untrained policy scores about -100.
    assert float(rows[-1]["normalized_score"]) > 70.0, rows
    assert float(rows[-1]["reward/expert"]) > float(rows[-1]["reward/agent"])
    assert float(rows[-1]["reward/accuracy"]) > 0.5


def test_trex_learns_from_preferences_alone(toy_expert_file: Path, toy_preference_file: Path, tmp_path: Path) -> None:
    """Standing still < random actions < the expert: the fixed T-REX reward is enough to reach the goal."""
    args = [*TOY_TRAIN_ARGS, "--method", "trex", "--expert", str(toy_expert_file), "--steps", "2000"]
    rows = _train_rows([*args, "--preferences", str(toy_preference_file)], tmp_path / "trex")
    assert float(rows[-1]["normalized_score"]) > 50.0, rows
    assert rows[0]["reward/train_loss"] == rows[-1]["reward/train_loss"]  # fit once, before the first step


@pytest.mark.parametrize("method", ["gail", "gaifo"])
def test_gail_and_gaifo_imitate_the_analytic_expert_with_ppo(
    method: str, toy_expert_file: Path, tmp_path: Path
) -> None:
    """With five discriminator passes per rollout the toy game oscillates before it settles (see the
    docs); forty steps per rollout of 256 settle it within 6144 steps."""
    args = [*TOY_PPO_ARGS, "--method", method, "--expert", str(toy_expert_file), "--steps", "6144"]
    rows = _train_rows([*args, "--leader.gda-steps", "40"], tmp_path / method)
    assert float(rows[-1]["normalized_score"]) > 70.0, rows
    assert float(rows[-1]["reward/expert"]) > float(rows[-1]["reward/agent"])
    assert np.isfinite(float(rows[-1]["losses/approx_kl"]))


@pytest.mark.parametrize(
    ("method", "options"),
    [
        ("gaifo", [*TOY_PPO_ARGS, "--steps", "2048", "--eval-every", "256", "--checkpoint-every", "512"]),
        (
            "bco",
            ["--env", "rankgame/PointGoal-v0", "--no-progress", "--steps", "2400", "--eval-every", "200"]
            + ["--checkpoint-every", "400", "--cloning.pre-steps", "400"],
        ),
    ],
)
def test_a_baseline_resumes_after_kill_9_with_every_evaluation_once(
    method: str, options: list[str], toy_expert_file: Path, tmp_path: Path
) -> None:
    out = tmp_path / method
    command = [sys.executable, "-m", "rankgame", "train", "--method", method, "--expert", str(toy_expert_file)]
    command += [*options, "--eval-episodes", "1", "--out", str(out)]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 240
    rows: list[dict[str, str]] = []
    while time.time() < deadline and not ((out / "checkpoint.npz").exists() and len(rows) >= 4):
        time.sleep(0.2)
        rows = _read_rows(out)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    every = int(options[options.index("--eval-every") + 1])
    total = int(options[options.index("--steps") + 1])
    assert len(_read_rows(out)) < total // every, "the run finished before it could be killed"
    resumed = subprocess.run([*command, "--resume"], capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert [int(row["env_steps"]) for row in _read_rows(out)] == list(range(every, total + 1, every))
