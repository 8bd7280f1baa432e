"""Offline rankings (pref): episodes from a replay buffer, ranking order, the snippet loss, the offline
chain's sampling and fit, and the pref methods end to end on the toy task."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import jax
import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_cli, run_main

from rankgame.cli import main
from rankgame.config import TrainConfig
from rankgame.data.preferences import episodes_from_replay, ranking_order, shipped_preferences_path
from rankgame.data.trajectories import TrajectoryFile, load_trajectories, save_trajectories
from rankgame.envs.make import make_env
from rankgame.envs.rollout import rollout
from rankgame.envs.toy import POINT_GOAL_ID
from rankgame.errors import RankGameError
from rankgame.game.rankings import Rankings, RankingsConfig, build_rankings
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import LOSSES, snippet_regression_loss
from rankgame.reward.offline_rankings import OfflineRankings
from rankgame.reward.player import RewardConfig, RewardPlayer
from rankgame.reward.ranking_data import RankingData
from rankgame.training import build_game


def _buffer(episodes: list[tuple[int, bool]], first_value: float = 0.0) -> dict[str, np.ndarray]:
    """Replay arrays of consecutive episodes ``(length, terminated)``; observations count up by one along
    an episode and jump by 100 at a reset, actions are 0.5, rewards 1."""
    obs, next_obs, dones = [], [], []
    value = first_value
    for length, terminated in episodes:
        for t in range(length):
            obs.append([value + t])
            next_obs.append([value + t + 1])
            dones.append(float(terminated and t == length - 1))
        value += 100.0
    n = len(obs)
    return {
        "buffer/obs": np.asarray(obs, np.float32),
        "buffer/acts": np.full((n, 1), 0.5, np.float32),
        "buffer/next_obs": np.asarray(next_obs, np.float32),
        "buffer/dones": np.asarray(dones, np.float32),
        "buffer/rews": np.ones(n, np.float32),
        "buffer/pos": np.asarray(n),
    }


def test_complete_episodes_are_cut_from_a_replay_buffer() -> None:
    # Horizon 3: a terminated 2-step episode, a 3-step episode cut by the time limit, then one in progress.
    arrays = _buffer([(2, True), (3, False), (2, False)])
    low, high = np.array([-2.0]), np.array([2.0])
    episodes = episodes_from_replay(arrays, 3, low, high, wrapped=False)
    assert [len(e) for e in episodes] == [2, 3]
    first, second = episodes
    np.testing.assert_array_equal(first.obs[:, 0], [0, 1, 2])
    np.testing.assert_array_equal(second.obs[:, 0], [100, 101, 102, 103])
    assert first.terminated.tolist() == [False, True] and not first.truncated.any()
    assert second.truncated.tolist() == [False, False, True] and not second.terminated.any()
    np.testing.assert_allclose(first.acts, 1.0)  # 0.5 in [-1, 1] is 1.0 in [-2, 2]
    assert second.ret == 3.0


def test_a_wrapped_buffer_is_read_from_its_oldest_transition_and_drops_the_overwritten_episode() -> None:
    arrays = _buffer([(3, False), (3, False), (3, False)])
    # The ring buffer's write position is 4: rows 4.. are older than rows ..3.
    pos = 4
    for key in ("buffer/obs", "buffer/acts", "buffer/next_obs", "buffer/dones", "buffer/rews"):
        arrays[key] = np.roll(arrays[key], pos, axis=0)
    arrays["buffer/pos"] = np.asarray(pos)
    episodes = episodes_from_replay(arrays, 3, np.array([-1.0]), np.array([1.0]), wrapped=True)
    assert [e.obs[0, 0] for e in episodes] == [100.0, 200.0]


def _file(returns: list[float], ranks: list[float] | None = None) -> TrajectoryFile:
    env = make_env(POINT_GOAL_ID)
    episodes = rollout(env, lambda obs: np.zeros(1, np.float32), len(returns), seed=0)
    scaled = [np.full(len(e), r / len(e), np.float32) for e, r in zip(episodes, returns, strict=True)]
    episodes = [replace(e, rews=rews) for e, rews in zip(episodes, scaled, strict=True)]
    metadata = {} if ranks is None else {"ranks": ranks}
    return TrajectoryFile(POINT_GOAL_ID, tuple(episodes), metadata)


def test_ranking_order_follows_returns_or_given_ranks() -> None:
    assert ranking_order(_file([5.0, -3.0, 2.0])).tolist() == [1, 2, 0]
    assert ranking_order(_file([5.0, -3.0, 2.0], ranks=[0, 2, 1])).tolist() == [0, 2, 1]
    with pytest.raises(RankGameError, match="one finite number per trajectory"):
        ranking_order(_file([5.0, -3.0], ranks=[1.0]))


def test_snippet_loss_hand_computed() -> None:
    # Snippets of l = 2: sums 3 and 8 against l k = 2 and 8: ((3 - 2) / 2)^2 = 0.25 and 0; mean 0.125.
    loss, metrics = snippet_regression_loss(np.array([[1.0, 2.0], [3.0, 5.0]]), np.array([1.0, 4.0]))
    assert float(loss) == pytest.approx(0.125) and float(metrics["snippet_mse"]) == pytest.approx(0.125)


def _constant_chain(p: int, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """Offline trajectory i holds the value i at every step (with t in column 1); the expert holds 99."""
    time = np.arange(horizon, dtype=np.float32)
    ranked = np.stack([np.stack([np.full(horizon, i, np.float32), time], axis=-1) for i in range(p)])
    expert = np.stack([np.full(horizon, 99.0, np.float32), time], axis=-1)[None]
    return ranked, expert


def test_offline_chain_samples_states_and_snippets_with_their_behaviors_targets() -> None:
    ranked, expert = _constant_chain(3, 20)
    targets = np.array([0.0, 1.0, 2.0, 5.0])
    chain = OfflineRankings(ranked, expert, targets, snippet_length=4)
    states, state_targets, snippets, snippet_targets = chain.sample(np.random.default_rng(0), 2, 400)
    assert states.shape == (2, 400, 2) and snippets.shape == (2, 100, 4, 2) and snippet_targets.shape == (2, 100)
    behavior = np.where(states[..., 0] == 99.0, 3, states[..., 0]).astype(int)
    np.testing.assert_array_equal(state_targets, targets[behavior])
    assert set(np.unique(behavior)) == {0, 1, 2, 3}  # every behavior drawn
    # A snippet is 4 consecutive steps of one trajectory, with that trajectory's target.
    assert np.all(np.diff(snippets[..., 1], axis=-1) == 1.0) and np.all(snippets[..., 0] == snippets[..., :1, 0])
    snippet_behavior = np.where(snippets[..., 0, 0] == 99.0, 3, snippets[..., 0, 0]).astype(int)
    np.testing.assert_array_equal(snippet_targets, targets[snippet_behavior])
    with pytest.raises(ValueError, match="snippet length"):
        OfflineRankings(ranked, expert, targets, snippet_length=21)
    with pytest.raises(ValueError, match="non-decreasing"):
        OfflineRankings(ranked, expert, targets[::-1], snippet_length=4)


def test_noisy_rankings_relabel_a_fixed_share_of_offline_labels_with_other_ranks() -> None:
    ranked, expert = _constant_chain(4, 200)
    targets = np.array([0.0, 1.0, 2.0, 3.0, 5.0])
    clean = OfflineRankings(ranked, expert, targets, snippet_length=10)
    np.testing.assert_array_equal(clean.state_rank, np.repeat(np.arange(5)[:, None], 200, axis=1))
    noisy = OfflineRankings(ranked, expert, targets, snippet_length=10, noise=0.4, noise_seed=1)
    own = np.arange(4)[:, None]
    for table in (noisy.state_rank, noisy.snippet_rank):
        flipped = table[:4] != own
        assert abs(flipped.mean() - 0.4) < 0.05  # about 40% of offline labels, never the expert's
        assert np.all(table[4] == 4) and np.all((table[:4] >= 0) & (table[:4] < 4))
    # The corruption is fixed for the run: sampled targets follow the noisy table.
    states, state_targets, snippets, snippet_targets = noisy.sample(np.random.default_rng(0), 1, 2000)
    behavior = np.where(states[0, :, 0] == 99.0, 4, states[0, :, 0]).astype(int)
    t = states[0, :, 1].astype(int)
    np.testing.assert_array_equal(state_targets[0], targets[noisy.state_rank[behavior, t]])
    with pytest.raises(ValueError, match="at least 2 offline trajectories"):
        OfflineRankings(ranked[:1], expert, targets[[0, 4]], snippet_length=10, noise=0.1)


def test_tabular_fit_regresses_each_offline_trajectory_to_its_rank_target() -> None:
    # One-hot states: the agent, three offline trajectories and the expert each visit their own state, so
    # every term of Eq. 6 is minimized at r(s) = the target of the behavior that visits s.
    eye = np.eye(5, dtype=np.float32)
    horizon = 10
    ranked = np.stack([np.tile(eye[1 + i], (horizon, 1)) for i in range(3)])
    expert = np.tile(eye[4], (1, horizon, 1))
    chain_targets = np.array([0.0, 10 / 3, 20 / 3, 10.0])
    chain = OfflineRankings(ranked, expert, chain_targets, snippet_length=5)
    data = RankingData(expert, np.array([0.0, 1.0]), np.array([0.0, 10.0]), holdout_fraction=0.0)
    rng = np.random.default_rng(0)
    data.add([np.tile(eye[0], (horizon, 1))], rng)
    cfg = RewardConfig(hidden_sizes=(32,), lr=3e-3, weight_decay=0.0, batch_size=512)
    layout = InputLayout(4, 0, "s")
    player = RewardPlayer(layout, LOSSES["regression"], cfg, Rankings(data, chain, offline_weight=0.3))
    state, _, metrics = player.fit_steps(player.init(jax.random.key(0)), 2000, rng)
    fitted = np.asarray(player.reward(state.params, eye))
    np.testing.assert_allclose(fitted, [0.0, 0.0, 10 / 3, 20 / 3, 10.0], atol=0.2)
    assert {"reward/term0/loss", "reward/term1/loss"} <= metrics.keys()  # Eq. 6's two terms
    with pytest.raises(ValueError, match="regresses targets"):
        build_rankings("pref", RankingsConfig(), expert, layout, 0.0, LOSSES["supremum"], preferences=ranked)


def test_pref_targets_follow_the_schedule_along_the_ranked_chain(toy_expert_file: Path, tmp_path: Path) -> None:
    prefs = save_trajectories(tmp_path / "prefs.npz", POINT_GOAL_ID, _file([3.0, 1.0, 2.0, 0.0]).trajectories)
    cfg = TrainConfig(env=POINT_GOAL_ID, method="rank-ral-pref", expert=toy_expert_file, preferences=prefs)
    game = build_game(cfg)
    chain = game.rankings.offline
    assert chain is not None and chain.n_behaviors == 5
    # exp schedule with beta = -1 at 0, 1/4, ..., 1 of the way from 0 to k = 10.
    expected = 10 * np.expm1(-np.arange(5) / 4) / np.expm1(-1.0)
    np.testing.assert_allclose(chain.targets, expected, rtol=1e-6)
    # Ranked worst first: the trajectory with return 0 is the bottom of the chain, the one with 3 the top.
    returns = load_trajectories(prefs).returns
    first_obs = [load_trajectories(prefs).trajectories[i].obs[0] for i in np.argsort(returns)]
    np.testing.assert_allclose(chain.ranked[:, 0, :2], np.stack(first_obs))
    np.testing.assert_array_equal(game.rankings.data.lambdas, [0.0, 1.0])  # the online ranking is agent vs expert


def test_preferences_command_and_pref_training_on_the_toy_task(toy_expert_file: Path, tmp_path: Path) -> None:
    from test_cli import TOY_EXPERT_ARGS

    run = tmp_path / "sac"
    assert run_cli(*TOY_EXPERT_ARGS, "--steps", "600", "--out", str(run)).returncode == 0
    prefs = tmp_path / "prefs.npz"
    result = run_cli("preferences", "--run", str(run), "--count", "6", "--seed", "3", "--out", str(prefs))
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    data = load_trajectories(prefs, env_id=POINT_GOAL_ID)
    assert summary["replay_episodes"] == 15 and len(data.trajectories) == 6  # 600 steps of 40-step episodes
    assert summary["returns_worst_to_best"] == pytest.approx(sorted(data.returns), rel=1e-5)
    assert data.metadata["source"] == "sac-replay" and data.metadata["command"].startswith("rankgame preferences")

    out = tmp_path / "ral-pref"
    args = [*TOY_TRAIN_ARGS, "--method", "rank-ral-pref", "--expert", str(toy_expert_file), "--preferences", str(prefs)]
    args += ["--steps", "2000", "--eval-every", "1000", "--eval-episodes", "10", "--out", str(out)]
    assert main(["train", *args]) == 0
    with (out / "metrics.csv").open() as handle:
        row = list(csv.DictReader(handle))[-1]
    # 0 is a uniformly random policy, 100 the expert; the untrained policy scores about -100.
    assert float(row["normalized_score"]) > 70.0, row
    assert float(row["reward/expert"]) > float(row["reward/agent"])


def test_bad_preference_input_gives_one_line_errors(
    toy_expert_file: Path, toy_preference_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["train", *TOY_TRAIN_ARGS, "--steps", "100", "--expert", str(toy_expert_file), "--out", str(tmp_path / "x")]
    assert_one_line_error(
        run_main(capsys, *base, "--method", "rank-pal-pref"), "no shipped preference data for 'rankgame/"
    )
    hopper_prefs = str(shipped_preferences_path("Hopper-v5"))
    assert_one_line_error(
        run_main(capsys, *base, "--method", "rank-pal-pref", "--preferences", hopper_prefs),
        "recorded on Hopper-v5, not",
    )
    assert_one_line_error(
        run_main(capsys, *base, "--preferences", hopper_prefs), "--preferences is used only by the pref methods"
    )
    one = save_trajectories(tmp_path / "one.npz", POINT_GOAL_ID, _file([1.0]).trajectories)
    assert_one_line_error(run_main(capsys, *base, "--method", "rank-ral-pref", "--preferences", str(one)), "at least 2")
    assert_one_line_error(
        run_main(capsys, *base, "--method", "rank-ral-pref", "--reward.pref-weight", "1.5"),
        "pref_weight must lie in [0, 1]",
    )
    pref = [*base, "--method", "rank-ral-pref", "--preferences", str(toy_preference_file)]
    assert_one_line_error(run_main(capsys, *pref, "--rankings.pref-noise", "2"), "pref_noise must lie in [0, 1]")
    only_pref = "--rankings.pref-noise is used only by the pref methods"
    assert_one_line_error(run_main(capsys, *base, "--pref-noise", "0.2"), only_pref)  # the old spelling still works
    assert_one_line_error(
        run_main(capsys, *pref, "--reward.snippet-length", "41"), "snippet length must lie in [1, 40]"
    )
    assert_one_line_error(run_main(capsys, "preferences", "--run", str(tmp_path)), "no checkpoint.npz in")
    assert_one_line_error(run_main(capsys, "preferences", "--count", "1"), "--count must be at least 2")
