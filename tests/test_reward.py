"""Reward player: targets, losses (hand-computed), mixup, features, and the tabular closed form (Eq. 9)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rankgame.game.leaders import Leader, LeaderConfig, make_leader
from rankgame.game.rankings import Rankings
from rankgame.nets import SpectralDense
from rankgame.reward.inputs import InputLayout, parse_obs_columns
from rankgame.reward.losses import LOSSES, bound_reward, regression_ranking_loss, supremum_loss, weighted_sum
from rankgame.reward.player import RewardConfig, RewardPlayer, RewardState
from rankgame.reward.ranking_data import RankingData
from rankgame.reward.targets import lambda_grid, target_schedule


def _layout(dim: int) -> InputLayout:
    """State-only reward inputs of ``dim`` entries, the last one the absorbing flag."""
    return InputLayout(dim - 1, 0, "s")


def _player(
    data: RankingData, dim: int, cfg: RewardConfig | None = None, loss: str = "regression", **kwargs: object
) -> RewardPlayer:
    return RewardPlayer(_layout(dim), LOSSES[loss], cfg or RewardConfig(), Rankings(data), **kwargs)  # type: ignore[arg-type]


def test_exp_schedule_matches_the_published_targets() -> None:
    # exp with beta = -1 on the grid 0, 0.2, ..., 1 between -10 and 10 (the authors' code).
    targets = target_schedule(lambda_grid(4), -10.0, 10.0, "exp", -1.0)
    np.testing.assert_allclose(targets, [-10, -4.27, 0.43, 4.27, 7.42, 10], atol=0.01)


def test_linear_schedule_and_limits() -> None:
    np.testing.assert_allclose(target_schedule(np.array([0, 0.5, 1]), 0, 10, "linear"), [0, 5, 10])
    np.testing.assert_allclose(target_schedule(np.array([0, 0.5, 1]), 0, 10, "exp", 0.0), [0, 5, 10])
    targets = target_schedule(lambda_grid(3), 0, 10, "exp", 2.0)
    assert np.all(np.diff(targets) > 0) and np.diff(targets)[0] < np.diff(targets)[-1]  # beta > 0: gaps grow
    assert targets.dtype == np.float64  # targets stay floats, never truncated
    # beta = 2 at lambda = 1/2: 10 (e - 1) / (e^2 - 1) = 10 / (e + 1).
    np.testing.assert_allclose(target_schedule(np.array([0.5]), 0, 10, "exp", 2.0), [10 / (np.e + 1)])
    for beta in (-1000.0, 1000.0):  # far past where e^beta overflows: still finite, ordered, 0 to 10
        extreme = target_schedule(lambda_grid(4), 0, 10, "exp", beta)
        assert np.isfinite(extreme).all() and np.all(np.diff(extreme) >= 0) and extreme[[0, -1]].tolist() == [0, 10]
    with pytest.raises(ValueError, match="unknown target schedule"):
        target_schedule(np.array([0.0, 1.0]), 0, 1, "cubic")  # type: ignore[arg-type]


def test_regression_loss_hand_computed() -> None:
    # L_k with k = 2: agent outputs (1, 0) -> target 0; expert outputs (2, 4) -> target 2.
    raw = jnp.array([1.0, 0.0, 2.0, 4.0])
    targets = jnp.array([0.0, 0.0, 2.0, 2.0])
    loss, metrics = regression_ranking_loss(raw, targets)
    assert float(loss) == pytest.approx((1 + 0 + 0 + 4) / 4)
    weighted, _ = regression_ranking_loss(raw, targets, jnp.array([1.0, 1.0, 1.0, 0.0]))
    assert float(weighted) == pytest.approx(1 / 3)


def test_supremum_loss_hand_computed() -> None:
    loss, metrics = supremum_loss(jnp.array([1.0, 3.0, 5.0, 9.0]), jnp.array([0.0, 0.0, 1.0, 1.0]))
    assert float(metrics["gap"]) == pytest.approx(7.0 - 2.0)
    assert float(loss) == pytest.approx(-5.0)
    # Padding rows (weight 0) count in neither mean: agent rows 1, 3 and expert rows 5, 9 remain.
    bounded = jnp.array([1.0, 3.0, 5.0, 9.0, 0.0, 0.0, 0.0])
    is_expert = jnp.array([0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    weights = jnp.array([1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    padded, padded_metrics = supremum_loss(bounded, is_expert, weights)
    assert float(padded_metrics["gap"]) == pytest.approx(5.0) and float(padded) == pytest.approx(-5.0)


def test_weighted_sum_of_losses() -> None:
    total, metrics = weighted_sum([(0.3, (jnp.array(2.0), {})), (0.7, (jnp.array(4.0), {"mse": jnp.array(4.0)}))])
    assert float(total) == pytest.approx(0.3 * 2 + 0.7 * 4)
    assert float(metrics["term1/mse"]) == 4.0


def test_bounds_keep_rewards_inside_and_tanh_keeps_gradients() -> None:
    raw = jnp.array([-30.0, 0.5, 30.0])
    np.testing.assert_allclose(bound_reward(raw, 10.0, "clip"), [-10, 0.5, 10])
    assert float(jnp.max(jnp.abs(bound_reward(raw, 10.0, "tanh")))) < 10.0
    grad = jax.grad(lambda x: bound_reward(x, 10.0, "tanh").sum())(raw)
    assert float(jnp.min(grad)) > 0.0


def test_absorbing_padding_of_an_early_terminated_episode() -> None:
    obs = np.arange(8, dtype=np.float32).reshape(4, 2)  # T = 3 steps
    acts = np.full((3, 1), 0.5, np.float32)
    feats = InputLayout(2, 1, "sa").episode(obs, acts, terminated=True, horizon=5)
    assert feats.shape == (5, 2 + 1 + 1)
    np.testing.assert_array_equal(feats[:3, :2], obs[:3])  # real states s_0..s_2
    np.testing.assert_array_equal(feats[:3, 2], 0.0)  # flag off
    np.testing.assert_array_equal(feats[3:], [[0, 0, 1, 0], [0, 0, 1, 0]])  # absorbing, zero action
    ss = InputLayout(2, 1, "ss").episode(obs, acts, terminated=True, horizon=5)
    np.testing.assert_array_equal(ss[2], [4, 5, 0, 0, 0, 1])  # last real step leads into s_abs
    full = InputLayout(2, 1, "s").episode(obs, acts, terminated=False, horizon=3)
    np.testing.assert_array_equal(full[:, :2], obs[:3])
    with pytest.raises(ValueError, match="cannot be aligned"):
        InputLayout(2, 1, "s").episode(obs, acts, terminated=False, horizon=5)


def test_reward_observation_entries_are_parsed_and_mapped_to_input_columns() -> None:
    assert parse_obs_columns("all", 4) == (0, 1, 2, 3)
    assert parse_obs_columns("0:2, 3", 5) == (0, 1, 3)
    assert parse_obs_columns("4 0:1", 5) == (4, 0)
    for spec, reason in [
        ("0:6", "inside the 5 observation entries"),
        ("2:2", "non-empty range"),
        ("a", "neither an index nor a range"),
        ("0:2:1", "neither an index nor a range"),
        ("0:2,1", "at most once"),
        ("", "at least one"),
    ]:
        with pytest.raises(ValueError, match=reason):
            parse_obs_columns(spec, 5)
    # obs_dim 3 (flag at index 3), act_dim 2, entries 0 and 2 kept:
    assert InputLayout(3, 2, "s").columns((0, 2)) == (0, 2, 3)
    assert InputLayout(3, 2, "ss").columns((0, 2)) == (0, 2, 3, 4, 6, 7)
    assert InputLayout(3, 2, "sa").columns((0, 2)) == (0, 2, 3, 4, 5)
    assert InputLayout(3, 2, "sa").columns((0, 1, 2)) is None  # every entry: no column selection


def test_the_reward_reads_only_its_columns() -> None:
    data = RankingData(np.zeros((1, 2, 4), np.float32), np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.0)
    player = _player(data, 4, columns=(1, 3))
    state = player.init(jax.random.key(0))
    assert state.params["params"]["MLP_0"]["Dense_0"]["kernel"].shape == (2, 64)
    x = jax.random.normal(jax.random.key(1), (8, 4))
    ignored = x.at[:, 0].set(5.0).at[:, 2].set(-5.0)
    np.testing.assert_array_equal(player.reward(state.params, x), player.reward(state.params, ignored))
    assert not np.allclose(player.reward(state.params, x), player.reward(state.params, x.at[:, 1].add(1.0)))


def test_mixup_is_time_aligned_with_scheduled_targets() -> None:
    expert = (10.0 + np.arange(6, dtype=np.float32) ** 2).reshape(1, 3, 2)
    lambdas = np.array([0.0, 0.5, 1.0])
    data = RankingData(expert, lambdas, np.array([0.0, 4.0, 10.0]), holdout_fraction=0.0)
    agent = np.arange(6, dtype=np.float32).reshape(3, 2)
    data.add([agent], np.random.default_rng(0))
    inputs, targets, is_expert = data.sample(np.random.default_rng(1), 4, 64)
    assert inputs.shape == (4, 64, 2) and targets.shape == (4, 64)
    for x, y, e in zip(inputs.reshape(-1, 2), targets.ravel(), is_expert.ravel(), strict=True):
        lam = {0.0: 0.0, 4.0: 0.5, 10.0: 1.0}[float(y)]
        t = [i for i in range(3) if np.allclose(x, agent[i] + lam * (expert[0, i] - agent[i]))]
        assert len(t) == 1  # the mixture of one time step with the expert at the same step
        assert e == (lam == 1.0)


@pytest.mark.parametrize("time_aligned", [True, False])
def test_state_mixup_pairs_agent_steps_with_expert_steps_from_any_time(time_aligned: bool) -> None:
    # Agent step t is (t, 0) and expert step t' is (0, 100 + t'), so the half-way mixture
    # (t / 2, 50 + t' / 2) tells which two steps were mixed.
    horizon = 5
    steps = np.arange(horizon, dtype=np.float32)
    expert = np.stack([np.zeros(horizon), 100.0 + steps], axis=1)[None].astype(np.float32)
    agent = np.stack([steps, np.zeros(horizon)], axis=1).astype(np.float32)
    data = RankingData(expert, np.array([0.0, 0.5, 1.0]), np.array([0.0, 4.0, 10.0]), 0.3, time_aligned=time_aligned)
    data.add([agent] * 20, np.random.default_rng(0))
    inputs, targets, _ = data.sample(np.random.default_rng(1), 8, 256)
    halfway = inputs[targets == 4.0]
    pairs = np.rint(np.column_stack([2 * halfway[:, 0], 2 * halfway[:, 1] - 100])).astype(int)
    held_inputs, held_targets, _ = data.holdout()
    held = np.rint(2 * held_inputs[held_targets == 4.0]).astype(int)
    held_pairs = np.column_stack([held[:, 0], held[:, 1] - 100])
    if time_aligned:
        assert np.all(pairs[:, 0] == pairs[:, 1]) and np.all(held_pairs[:, 0] == held_pairs[:, 1])
    else:
        # Every (t, t') pair turns up: 25 pairs, each with probability 1/25 per draw over ~680 draws.
        assert len({tuple(pair) for pair in pairs}) == horizon * horizon
        assert np.mean(held_pairs[:, 0] != held_pairs[:, 1]) > 0.5
        assert np.array_equal(data.holdout()[0], held_inputs)  # the holdout stays fixed


def test_holdout_is_a_shuffled_share_of_rows() -> None:
    expert = np.zeros((2, 100, 1), np.float32)
    data = RankingData(expert, np.array([0.0, 1.0]), np.array([0.0, 1.0]), holdout_fraction=0.1)
    data.add([np.zeros((100, 1), np.float32)] * 20, np.random.default_rng(0))
    held = data.holdout_rows
    assert 120 < len(held) < 280  # about 10% of 2000 rows
    assert held[:, 0].min() < 5 and held[:, 0].max() > 15  # drawn across the data, not its tail
    inputs, targets, _ = data.holdout()
    assert len(inputs) == 2 * len(held)
    data.clear()
    assert data.n_trajectories == 0 and len(data.train_rows) == 0


def test_the_holdout_is_drawn_from_every_row_padding_included() -> None:
    # Inputs (x, flag): each trajectory is 10 real steps, then 90 absorbing rows (flag 1).
    expert = np.zeros((1, 100, 2), np.float32)
    trajectory = np.zeros((100, 2), np.float32)
    trajectory[10:, 1] = 1.0
    data = RankingData(expert, np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.5, _layout(2))
    data.add([trajectory] * 40, np.random.default_rng(0))
    held_steps = data.holdout_rows[:, 1]
    assert len(data.train_rows) + len(held_steps) == 4000  # every row is either trained on or held out
    assert (held_steps >= 10).mean() > 0.8 and 1800 < len(held_steps) < 2200  # half of all rows
    assert data.n_real_states == 400


def test_tabular_fit_approaches_the_closed_form() -> None:
    # One-hot states; agent and expert visit them with different frequencies. The pointwise minimizer
    # of L_k is r*(s) = k rho_E(s) / (rho_E(s) + rho_pi(s)) (App. A, Eq. 9).
    n_states, horizon, k = 4, 2000, 1.0
    rng = np.random.default_rng(0)
    rho_pi, rho_e = np.array([0.5, 0.3, 0.15, 0.05]), np.array([0.05, 0.15, 0.3, 0.5])
    eye = np.eye(n_states, dtype=np.float32)
    agent = eye[rng.choice(n_states, size=horizon, p=rho_pi)]
    expert = eye[rng.choice(n_states, size=horizon, p=rho_e)]
    data = RankingData(expert[None], np.array([0.0, 1.0]), np.array([0.0, k]), holdout_fraction=0.0)
    data.add([agent], rng)
    cfg = RewardConfig(hidden_sizes=(32,), lr=1e-3, weight_decay=0.0, batch_size=4096, r_max=10.0)
    player = _player(data, n_states, cfg)
    state, _, _ = player.fit_steps(player.init(jax.random.key(0)), 3000, rng)
    fitted = np.asarray(player.reward(state.params, eye))
    # Expected from the empirical visitation counts of this sample.
    p_pi, p_e = agent.mean(0), expert.mean(0)
    np.testing.assert_allclose(fitted, k * p_e / (p_e + p_pi), atol=0.03)


def test_spectral_dense_divides_the_kernel_by_its_largest_singular_value() -> None:
    layer = SpectralDense(2)
    params = {"params": {"kernel": jnp.array([[3.0, 0.0], [0.0, 1.0]]), "bias": jnp.array([0.5, -0.5])}}
    out = layer.apply(params, jnp.array([[1.0, 1.0], [2.0, -3.0]]))
    np.testing.assert_allclose(out, [[1.0 + 0.5, 1 / 3 - 0.5], [2.0 + 0.5, -1.0 - 0.5]], rtol=1e-6)
    # The gradient treats the singular vectors as constants: sigma = u^T W v = W00 here (u = v = e0),
    # and the second output at x = (1, 1) is (W01 + W11) / W00 + b1, whose gradient in W is
    # [[-(W01 + W11) / W00^2, 1 / W00], [0, 1 / W00]].
    grad = jax.grad(lambda p: layer.apply(p, jnp.array([[1.0, 1.0]]))[0, 1])(params)
    np.testing.assert_allclose(grad["params"]["kernel"], [[-1 / 9, 1 / 3], [0.0, 1 / 3]], rtol=1e-5, atol=1e-7)


def test_a_spectrally_normalized_reward_is_1_lipschitz_and_still_fits() -> None:
    rng = np.random.default_rng(0)
    expert = np.full((1, 100, 3), 1.5, np.float32)
    data = RankingData(expert, np.array([0.0, 1.0]), np.array([0.0, 1.0]), holdout_fraction=0.0)
    data.add([np.full((100, 3), -1.5, np.float32)], rng)
    cfg = RewardConfig(hidden_sizes=(32, 32), weight_decay=0.0, batch_size=256)
    player = _player(data, 3, cfg, spectral_norm=True)
    state = player.init(jax.random.key(0))
    big = jax.tree_util.tree_map(lambda w: 50.0 * w, state.params)  # normalization undoes any scale
    x, y = jax.random.normal(jax.random.key(1), (2, 512, 3)) * 3.0
    gap = np.abs(np.asarray(player.net.apply(big, x) - player.net.apply(big, y)))
    assert np.all(gap <= np.linalg.norm(np.asarray(x - y), axis=1) + 1e-4)
    state, _, _ = player.fit_steps(state, 400, rng)
    fitted = np.asarray(player.reward(state.params, jnp.array([[-1.5] * 3, [1.5] * 3])))
    np.testing.assert_allclose(fitted, [0.0, 1.0], atol=0.05)  # the points are ~5.2 apart: a gap of 1 fits


def test_supremum_player_separates_agent_and_expert() -> None:
    eye = np.eye(2, dtype=np.float32)
    data = RankingData(np.tile(eye[1], (1, 50, 1)), np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.0)
    data.add([np.tile(eye[0], (50, 1))], np.random.default_rng(0))
    player = _player(data, 2, RewardConfig(hidden_sizes=(16,), batch_size=64, r_max=5.0), loss="supremum")
    state, _, metrics = player.fit_steps(player.init(jax.random.key(0)), 1000, np.random.default_rng(1))
    assert metrics["reward/gap"] > 0.0  # the loss's own metric is reported
    rewards = np.asarray(player.reward(state.params, eye))
    assert rewards[1] - rewards[0] > 8.0 and np.all(np.abs(rewards) < 5.0)


def test_early_stopping_ends_and_keeps_the_best_holdout() -> None:
    rng = np.random.default_rng(0)
    expert = rng.normal(size=(1, 200, 3)).astype(np.float32) + 1.0
    data = RankingData(expert, lambda_grid(2), target_schedule(lambda_grid(2), 0, 10), holdout_fraction=0.1)
    data.add([rng.normal(size=(200, 3)).astype(np.float32) for _ in range(3)], rng)
    player = _player(data, 3, RewardConfig(batch_size=128))
    leader = make_leader("pal", LeaderConfig(patience=2, max_epochs=200))
    state = player.init(jax.random.key(0))
    holdout = player.holdout_batch(data)
    before = player.holdout_loss(state.params, holdout)
    state, metrics = leader.fit(player, state, rng)
    assert metrics["reward/epochs"] < 200  # stopping triggered
    assert metrics["reward/holdout_loss"] < before
    assert player.holdout_loss(state.params, holdout) == pytest.approx(metrics["reward/holdout_loss"], rel=1e-5)
    assert "reward/mse" in metrics  # the loss's own metric is reported


def test_real_states_are_counted_without_absorbing_padding() -> None:
    expert = np.zeros((1, 4, 2), np.float32)
    data = RankingData(expert, np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.5, _layout(2))
    short = np.array([[3.0, 0.0], [4.0, 0.0], [0.0, 1.0], [0.0, 1.0]], np.float32)  # 2 real steps, 2 absorbing
    data.add([short, np.zeros((4, 2), np.float32)], np.random.default_rng(0))
    assert data.n_real_states == 2 + 4
    held = len(data.holdout_rows)
    inputs, _, _ = data.holdout(max_rows=1)
    assert held > 1 and len(inputs) == 2  # one row, both mixtures
    restored = RankingData(expert, np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.5, _layout(2))
    restored.load_state_dict(data.state_dict())
    assert restored.n_real_states == 6 and len(restored.holdout_rows) == held


def _fit_steps_recorder(player: RewardPlayer, asked: list[int]) -> None:
    """Replace the player's gradient steps with a record of how many were asked for."""

    def fit_steps(state: RewardState, n: int, rng: np.random.Generator) -> tuple:
        asked.append(n)
        return state, 0.0, {}

    player.fit_steps = fit_steps  # type: ignore[method-assign]


@pytest.mark.parametrize(("passes", "expected"), [(1.0, 2), (2.5, 4), (0.01, 1)])
def test_ral_budget_is_passes_over_the_real_agent_states(passes: float, expected: int) -> None:
    # 3 trajectories x 400 real steps (+ 100 absorbing each), batch 800: |D| = 1200 real states, so
    # one pass is ceil(1200 / 800) = 2 gradient steps and 2.5 passes are 3000 / 800 -> 4.
    horizon = 500
    traj = np.zeros((horizon, 2), np.float32)
    traj[400:, 1] = 1.0  # the absorbing flag marks the padding
    data = RankingData(
        np.zeros((1, horizon, 2), np.float32), np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.1, _layout(2)
    )
    data.add([traj] * 3, np.random.default_rng(0))
    player = _player(data, 2, RewardConfig(batch_size=800))
    asked: list[int] = []
    _fit_steps_recorder(player, asked)
    make_leader("ral", LeaderConfig(ral_passes=passes)).fit(
        player, player.init(jax.random.key(0)), np.random.default_rng(1)
    )
    assert asked == [expected]


@pytest.mark.parametrize(("rows", "ral_steps", "pal_epoch"), [("real", 3, 6), ("all", 4, 8)])
def test_budget_rows_decides_whether_absorbing_padding_counts(rows: str, ral_steps: int, pal_epoch: int) -> None:
    # 3 trajectories x (400 real + 100 absorbing) rows, no holdout, batch 400, 2 mixtures per row.
    # RAL, one pass: real ceil(1200 / 400) = 3 steps, all ceil(1500 / 400) = 4.
    # PAL, one epoch (the only one without a holdout): real 1200 * 2 / 400 = 6, all 1500 * 2 / 400 -> 8.
    traj = np.zeros((500, 2), np.float32)
    traj[400:, 1] = 1.0
    data = RankingData(np.zeros((1, 500, 2), np.float32), np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.0, _layout(2))
    data.add([traj] * 3, np.random.default_rng(0))
    player = _player(data, 2, RewardConfig(batch_size=400))
    asked: list[int] = []
    _fit_steps_recorder(player, asked)
    for leader in ("ral", "pal"):
        make_leader(leader, LeaderConfig(), rows=rows).fit(  # type: ignore[arg-type]
            player, player.init(jax.random.key(0)), np.random.default_rng(1)
        )
    assert asked == [ral_steps, pal_epoch]


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_early_stopping_needs_a_relative_improvement_whatever_the_sign_of_the_loss(sign: float) -> None:
    # The holdout loss improves by 0.1% per epoch, less than MIN_IMPROVEMENT (1%): fitting stops after
    # `patience` epochs whether the loss is positive (regression) or negative (the supremum loss).
    data = RankingData(np.zeros((1, 50, 2), np.float32), np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.2)
    data.add([np.ones((50, 2), np.float32)] * 2, np.random.default_rng(0))
    player = _player(data, 2, RewardConfig(batch_size=16))
    losses = iter(sign * 10.0 * (1.0 - 0.001 * sign * i) for i in range(100))
    player.holdout_loss = lambda params, holdout: next(losses)  # type: ignore[method-assign]
    _fit_steps_recorder(player, [])
    leader = make_leader("pal", LeaderConfig(patience=2, max_epochs=20))
    _, metrics = leader.fit(player, player.init(jax.random.key(0)), np.random.default_rng(1))
    assert metrics["reward/epochs"] == 2.0
    assert metrics["reward/holdout_loss"] == pytest.approx(sign * 10.0 * (1.0 - 0.002 * sign))


@pytest.mark.parametrize(
    ("leader", "budget", "expected"),
    [("pal", None, "holdout"), ("ral", None, "passes"), ("pal", "passes", "passes"), ("ral", "holdout", "holdout")],
)
def test_the_budget_option_swaps_the_leaders_budgets(
    monkeypatch: pytest.MonkeyPatch, leader: str, budget: str | None, expected: str
) -> None:
    data = RankingData(np.zeros((1, 10, 2), np.float32), np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.1, _layout(2))
    data.add([np.zeros((10, 2), np.float32)] * 3, np.random.default_rng(0))
    player = _player(data, 2, RewardConfig(batch_size=4))
    used: list[str] = []
    asked: list[int] = []
    _fit_steps_recorder(player, asked)
    monkeypatch.setattr(
        Leader, "_fit_until_converged", lambda self, player, state, rng: (used.append("holdout"), (state, {}))[1]
    )
    chosen = make_leader(leader, LeaderConfig(ral_passes=2.0), budget=budget)  # type: ignore[arg-type]
    assert chosen.keeps_history == (leader == "ral")
    chosen.fit(player, player.init(jax.random.key(0)), np.random.default_rng(1))
    # 30 real states, 2 passes of batch 4: ceil(60 / 4) = 15 gradient steps.
    assert (used, asked) == ((["holdout"], []) if expected == "holdout" else ([], [15]))


def test_a_ranking_gradient_penalty_keeps_the_reward_from_jumping_between_close_inputs() -> None:
    """Agent and expert states 0.17 apart: L_k alone fits targets 0 and 1, a reward whose slope is about
    6; with the penalty (weight 10, slope 1 at the interpolations) the gap stays near the distance."""
    gaps = {}
    for weight in (0.0, 10.0):
        rng = np.random.default_rng(0)
        data = RankingData(np.full((1, 100, 3), 0.05, np.float32), np.array([0.0, 1.0]), np.array([0.0, 1.0]), 0.0)
        data.add([np.full((100, 3), -0.05, np.float32)], rng)
        cfg = RewardConfig(hidden_sizes=(32, 32), weight_decay=0.0, batch_size=256, ranking_gradient_penalty=weight)
        player = RewardPlayer(_layout(3), LOSSES["regression"], cfg, Rankings(data, penalty_points=weight > 0))
        state, _, metrics = player.fit_steps(player.init(jax.random.key(0)), 600, rng)
        assert ("reward/gradient_penalty" in metrics) == (weight > 0)
        low, high = np.asarray(player.reward(state.params, jnp.array([[-0.05] * 3, [0.05] * 3])))
        gaps[weight] = high - low
    assert gaps[0.0] > 0.9
    assert gaps[10.0] < 0.5
