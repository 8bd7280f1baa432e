"""Standing still ranked below the expert (``--rankings.still-weight``, ``--rankings.still-poses``): the
inputs of staying in a state, the closed-form fits on one-hot states, the settings it refuses, and runs
on the toy task."""

from __future__ import annotations

import csv
from pathlib import Path

import jax
import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_main

from rankgame.game.rankings import Rankings, RankingsConfig, build_rankings
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import LOSSES
from rankgame.reward.player import RewardConfig, RewardPlayer


def test_standing_still_holds_the_first_state_of_each_input_for_the_horizon() -> None:
    first = np.array([[1.0, 2.0, 0.0, 5.0, 6.0, 0.0]], np.float32)  # obs_dim 2: [s, flag, s', flag']
    held = InputLayout(2, 3, "ss").standing_still(first, 4)
    assert held.shape == (1, 4, 6)
    np.testing.assert_array_equal(held[0], np.tile([1.0, 2.0, 0.0, 1.0, 2.0, 0.0], (4, 1)))  # (s, s)
    first_sa = np.array([[1.0, 2.0, 0.0, 0.5, -0.5, 1.0]], np.float32)
    held_sa = InputLayout(2, 3, "sa").standing_still(first_sa, 2)
    np.testing.assert_array_equal(held_sa[0], np.tile([1.0, 2.0, 0.0, 0.0, 0.0, 0.0], (2, 1)))  # zero action
    held_s = InputLayout(2, 3, "s").standing_still(first[:, :3], 3)
    np.testing.assert_array_equal(held_s[0], np.tile([1.0, 2.0, 0.0], (3, 1)))


def test_held_still_stays_one_step_in_the_state_each_input_starts_in() -> None:
    inputs = np.array([[[1.0, 2.0, 0.0, 5.0, 6.0, 0.0], [5.0, 6.0, 0.0, 0.0, 0.0, 1.0]]], np.float32)  # (1, 2, 6)
    held = InputLayout(2, 3, "ss").held_still(inputs)
    np.testing.assert_array_equal(held[0], [[1.0, 2.0, 0.0, 1.0, 2.0, 0.0], [5.0, 6.0, 0.0, 5.0, 6.0, 0.0]])
    held_sa = InputLayout(2, 1, "sa").held_still(inputs[..., :4])
    np.testing.assert_array_equal(held_sa[0], [[1.0, 2.0, 0.0, 0.0], [5.0, 6.0, 0.0, 0.0]])


def _one_hot_rankings(still_weight: float, horizon: int) -> tuple[Rankings, np.ndarray]:
    """The agent stays in state 1; the expert starts in state 0 and is in state 3 after that."""
    eye = np.eye(4, dtype=np.float32)
    expert = np.concatenate([eye[None, :1], np.tile(eye[3], (1, horizon - 1, 1))], axis=1)
    layout = InputLayout(3, 0, "s")  # one-hot of 4 entries: 3 "observation" entries and the flag, unused here
    config = RankingsConfig(k=10.0, still_weight=still_weight)
    rankings = build_rankings("vanilla", config, expert, layout, 0.0, LOSSES["regression"])
    assert isinstance(rankings, Rankings)
    rankings.data.add([np.tile(eye[1], (horizon, 1))], np.random.default_rng(0))
    return rankings, eye


@pytest.mark.parametrize("still_weight", [0.0, 0.3])
def test_the_fit_pays_the_initial_state_the_closed_form_of_the_weighted_rankings(still_weight: float) -> None:
    # Regression to targets on one-hot states fits each state to the weighted mean of its targets. The
    # initial state 0 is the expert's first step (target k = 10, weight 1 / (2H) in each of the two
    # chains, whose weights are 1 - w and w) and, with weight w, all of standing still (target 0,
    # weight 1 / 2 of its chain): r(0) = 10 (1 / 2H) / (1 / 2H + w / 2) = 10 / (1 + w H).
    horizon = 10
    rankings, eye = _one_hot_rankings(still_weight, horizon)
    cfg = RewardConfig(hidden_sizes=(32,), lr=3e-3, weight_decay=0.0, batch_size=512)
    player = RewardPlayer(InputLayout(3, 0, "s"), LOSSES["regression"], cfg, rankings)
    state, _, _ = player.fit_steps(player.init(jax.random.key(0)), 3000, np.random.default_rng(1))
    fitted = np.asarray(player.reward(state.params, eye))
    expected_initial = 10.0 / (1.0 + still_weight * horizon)
    np.testing.assert_allclose(fitted[[0, 1, 3]], [expected_initial, 0.0, 10.0], atol=0.25)


def test_every_expert_pose_held_still_fits_the_closed_form_where_the_expert_stands_still() -> None:
    # One-hot states a, b, c, d, x (obs_dim 5, flag 0); the expert's (s, s') inputs are (a, b), (b, b),
    # (b, c), (c, d): it stands still once, in b. Vanilla rankings: in each chain half of a batch is the
    # chain's agent rows (target 0), half the expert's (target k = 10), each of the H = 4 steps alike.
    # The agent stays in x. Held still, the expert's poses are (a, a), (b, b), (b, b), (c, c): so (b, b)
    # is an expert input with weight (1 - w) / 8 + w / 8 and a standing one with weight 2 w / 8, and
    # regression fits r(b, b) = 10 / (1 + 2 w); (a, a) and (c, c) only stand still, so they get 0.
    w = 0.3
    eye = np.eye(6, dtype=np.float32)  # entry 5 is the absorbing flag
    a, b, c, d, x = eye[:5]
    expert = np.stack([np.concatenate(pair) for pair in [(a, b), (b, b), (b, c), (c, d)]])[None]
    layout = InputLayout(5, 0, "ss")
    config = RankingsConfig(k=10.0, still_weight=w, still_poses="expert")
    rankings = build_rankings("vanilla", config, expert, layout, 0.0, LOSSES["regression"])
    assert isinstance(rankings, Rankings)
    rankings.data.add([np.tile(np.concatenate([x, x]), (4, 1))], np.random.default_rng(0))
    cfg = RewardConfig(hidden_sizes=(64,), lr=3e-3, weight_decay=0.0, batch_size=512)
    player = RewardPlayer(layout, LOSSES["regression"], cfg, rankings)
    state, _, _ = player.fit_steps(player.init(jax.random.key(0)), 3000, np.random.default_rng(1))
    probes = np.stack([np.concatenate(pair) for pair in [(b, b), (a, a), (c, c), (a, b), (b, c), (x, x)]])
    fitted = np.asarray(player.reward(state.params, probes))
    np.testing.assert_allclose(fitted, [10.0 / (1.0 + 2 * w), 0.0, 0.0, 10.0, 10.0, 0.0], atol=0.3)


def test_expert_poses_held_still_leave_out_the_absorbing_padding() -> None:
    layout = InputLayout(1, 0, "ss")
    episode = layout.episode(np.array([[0.0], [1.0], [2.0]], np.float32), np.zeros((2, 0)), True, 6)  # 2 real steps
    config = RankingsConfig(still_weight=0.2, still_poses="expert")
    rankings = build_rankings("auto", config, episode[None], layout, 0.0, LOSSES["regression"])
    assert isinstance(rankings, Rankings) and rankings.still is not None
    assert sorted(rankings.still.train_rows[:, 1].tolist()) == [0, 1]  # (s, s) at steps 0 and 1 only


@pytest.mark.parametrize("poses", ["initial", "expert"])
def test_a_changed_expert_brings_its_own_poses_to_stand_still(poses: str) -> None:
    layout = InputLayout(1, 0, "ss")
    old = layout.episode(np.array([[0.0], [1.0], [2.0]], np.float32), np.zeros((2, 0)), False, 2)[None]
    new = layout.episode(np.array([[5.0], [6.0], [7.0]], np.float32), np.zeros((2, 0)), False, 2)[None]
    config = RankingsConfig(still_weight=0.2, still_poses=poses)
    rankings = build_rankings("auto", config, old, layout, 0.0, LOSSES["regression"])
    assert isinstance(rankings, Rankings)
    rankings.replace_expert(new, np.random.default_rng(0))
    assert rankings.still is not None
    np.testing.assert_array_equal(rankings.still.expert, new)
    # the states held still are the new expert's: (5, 5) twice from its start, or (5, 5) and (6, 6)
    held = rankings.still.agent[0, :, [0, 2]].T
    expected = [[5.0, 5.0], [5.0, 5.0]] if poses == "initial" else [[5.0, 5.0], [6.0, 6.0]]
    np.testing.assert_array_equal(held, expected)


def test_standing_still_survives_pal_clearing_the_agent_data() -> None:
    rankings, _ = _one_hot_rankings(0.3, 10)
    rankings.data.clear()
    assert rankings.still is not None and rankings.still.n_trajectories == 1
    assert rankings.still.n_real_states == 10 and len(rankings.still.holdout_rows) == 0


def test_still_weight_refuses_what_makes_no_sense(toy_expert_file: Path, tmp_path: Path, capsys) -> None:
    expert = np.zeros((1, 5, 4), np.float32)
    layout = InputLayout(3, 0, "s")
    with pytest.raises(ValueError, match=r"still_weight must lie in \[0, 1\)"):
        build_rankings("auto", RankingsConfig(still_weight=1.0), expert, layout, 0.0, LOSSES["regression"])
    with pytest.raises(ValueError, match="needs a loss that regresses targets"):
        build_rankings("vanilla", RankingsConfig(still_weight=0.2), expert, layout, 0.0, LOSSES["supremum"])
    with pytest.raises(ValueError, match=r"still_poses expert needs an \(s, s'\) reward"):
        expert_poses = RankingsConfig(still_weight=0.2, still_poses="expert")
        build_rankings("auto", expert_poses, expert, layout, 0.0, LOSSES["regression"])
    base = ["train", *TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--steps", "100", "--out", str(tmp_path / "x")]
    assert_one_line_error(
        run_main(capsys, *base, "--method", "dacfo", "--rankings.still-weight", "0.2"),
        "--rankings.still-weight is not used by dacfo",
    )
    assert_one_line_error(run_main(capsys, *base, "--rankings.still-weight", "-0.1"), "still_weight must lie in")
    poses = ["--rankings.still-poses", "expert"]
    assert_one_line_error(run_main(capsys, *base, *poses, "--rankings.still-weight", "0.2"), "use --reward-input ss")
    assert_one_line_error(run_main(capsys, *base, *poses, "--reward-input", "ss"), "still_poses needs still_weight > 0")
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    "poses", [[], ["--rankings.still-poses", "expert", "--reward-input", "ss"]], ids=["initial", "expert"]
)
def test_a_run_with_standing_still_ranked_trains_and_resumes(
    poses: list[str], toy_expert_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    args = ["train", *TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--rankings.still-weight", "0.3", *poses]
    assert run_main(capsys, *args, "--steps", "400", "--out", str(out)).returncode == 0
    assert run_main(capsys, *args, "--steps", "800", "--out", str(out), "--resume").returncode == 0
    with (out / "metrics.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    steps = [int(float(r["env_steps"])) for r in rows]
    assert steps == sorted(set(steps)) and steps[-1] == 800
    assert all(np.isfinite(float(r["reward/train_loss"])) for r in rows if r["reward/train_loss"])
