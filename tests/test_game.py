"""The ranking game end to end on the toy task: learning, resume after kill -9, and bad input."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_main, toy_train_args

from rankgame.checkpoint import flatten_tree, load_checkpoint
from rankgame.cli import main
from rankgame.config import TrainConfig
from rankgame.data.trajectories import Trajectory, load_trajectories, save_trajectories
from rankgame.envs.make import make_env
from rankgame.envs.rollout import rollout
from rankgame.envs.toy import POINT_GOAL_EDGE_ID, point_goal_expert
from rankgame.game.loop import FINISHED_KEY, RankingGame
from rankgame.game.methods import METHODS
from rankgame.policy.io import load_policy
from rankgame.policy.sac import SACConfig
from rankgame.reward.player import RewardConfig
from rankgame.training import build_game, train


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "metrics.csv").open() as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize(
    ("method", "options"),
    [
        ("rank-pal-auto", ()),
        ("rank-ral-auto", ()),
        ("rank-pal-auto", ("--reward-obs", "1")),
        ("rank-pal-auto", ("--reward.policy-window", "3")),
        ("rank-pal-auto", ("--reward.ranking-gradient-penalty", "10")),
    ],
)
def test_pal_and_ral_imitate_the_analytic_expert(
    method: str, options: tuple[str, ...], toy_expert_file: Path, tmp_path: Path
) -> None:
    """``--reward-obs 1``: a reward that reads only the distance to the goal (entry 1) suffices; so does
    paying the policy the mean of the last three rewards, or a reward kept smooth by a gradient penalty."""
    out = tmp_path / method
    args = [*TOY_TRAIN_ARGS, "--method", method, "--expert", str(toy_expert_file), "--steps", "2000", *options]
    assert main(["train", *args, "--eval-every", "1000", "--eval-episodes", "10", "--out", str(out)]) == 0
    rows = _rows(out)
    final = float(rows[-1]["normalized_score"])
    # 0 is a uniformly random policy, 100 the expert; the untrained policy scores about -100.
    assert final > 70.0, rows
    assert float(rows[-1]["reward/expert"]) > float(rows[-1]["reward/agent"])
    assert rows[-1]["eval_success"] == ""  # the toy task reports no success
    assert ("reward/gradient_penalty" in rows[-1]) == ("--reward.ranking-gradient-penalty" in options)


@pytest.mark.parametrize(
    ("method", "setting", "reward_input"), [("rank-pal-auto", "lfd", "default"), ("rank-ral-auto", "lfo", "ss")]
)
def test_the_game_learns_to_stay_on_a_ledge_it_could_step_off(
    method: str, setting: str, reward_input: str, tiny_sac: SACConfig, tmp_path: Path
) -> None:
    """Early termination: episodes that step off the ledge are padded with the absorbing state."""
    env = make_env(POINT_GOAL_EDGE_ID)
    expert = save_trajectories(tmp_path / "edge.npz", POINT_GOAL_EDGE_ID, rollout(env, point_goal_expert, 5, seed=0))
    cfg = TrainConfig(
        env=POINT_GOAL_EDGE_ID,
        method=method,
        expert=expert,
        setting=setting,
        reward_input=reward_input,
        sac=tiny_sac,
        reward=replace(RewardConfig(), batch_size=256),
    )
    game = build_game(cfg)
    padded = False
    for step in range(1, 2401):
        game.env_step()
        padded |= any((~game.layout.is_real(features)).any() for features in game.finished)
        if step % game.n_pol == 0:
            game.reward_turn()
    assert padded  # some early episodes (random actions) stepped off and were padded
    episodes = rollout(env, game.learner.policy(), 10, seed=123)
    # Every episode lasts the full 40 steps; the return of the analytic expert is about -0.8, a uniformly
    # random policy's about -20 and the untrained policy's (which barely moves) about -25.
    assert [len(episode) for episode in episodes] == [40] * 10
    assert np.mean([episode.ret for episode in episodes]) > -10.0


def test_every_method_runs(toy_expert_file: Path, toy_preference_file: Path, tmp_path: Path) -> None:
    for method, pieces in METHODS.items():
        out = tmp_path / method
        steps = "512" if pieces.policy == "ppo" else "480"  # whole PPO rollouts of 256 steps
        args = [*toy_train_args(method), "--method", method, "--expert", str(toy_expert_file), "--steps", steps]
        if pieces.uses_preferences:
            args += ["--preferences", str(toy_preference_file)]
        assert main(["train", *args, "--eval-every", steps, "--eval-episodes", "1", "--out", str(out)]) == 0
        last = _rows(out)[-1]
        for column in ("eval_return", "reward/train_loss", "reward/agent", "reward/expert", "losses/critic"):
            assert np.isfinite(float(last[column])), (method, column, last)


def test_a_variant_without_contact_forces_imitates_its_tasks_shipped_expert_through_27_entries() -> None:
    game = build_game(TrainConfig(env="rankgame/AntNoContact-v5"))
    assert game.learner.spec.obs_dim == 27
    assert game.rankings.data.expert.shape == (1, 1000, 28)  # one trajectory, H = 1000, 27 entries and the flag
    assert game.scale.expert_return == pytest.approx(5004.7, abs=0.1)  # the Ant-v5 expert's scale


def test_a_checkpoint_restores_every_piece_of_the_game(toy_expert_file: Path, tmp_path: Path) -> None:
    cfg = TrainConfig(
        env="rankgame/PointGoal-v0",
        method="rank-ral-auto",
        expert=toy_expert_file,
        seed=3,
        sac=replace(SACConfig(), hidden_sizes=(16,), batch_size=32, start_steps=100, update_after=100),
        reward=replace(RewardConfig(), hidden_sizes=(16,), batch_size=64, policy_window=3),
    )
    game = build_game(cfg)
    for step in range(1, 4 * game.n_pol + 1):
        game.step(step)
    game.selection.best = 0.7
    restored = build_game(cfg)
    restored.restore(*game.checkpoint())

    def arrays(g: RankingGame) -> dict[str, np.ndarray]:
        _, learner_arrays = g.learner.checkpoint()
        reward = {**flatten_tree("reward", g.reward_state), **flatten_tree("policy_reward", g.policy_reward)}
        return {**learner_arrays, **reward, **g.rankings.data.state_dict()}

    saved, loaded = arrays(game), arrays(restored)
    assert int(game.policy_reward.count) == 4  # one reward per iteration
    assert saved.keys() == loaded.keys() and len(game.rankings.data.agent) == 4
    for key in saved:
        np.testing.assert_array_equal(saved[key], loaded[key], err_msg=key)
    assert restored.learner.env_steps == game.learner.env_steps == 4 * game.n_pol
    assert restored.rng.bit_generator.state == game.rng.bit_generator.state
    assert restored.learner.rng.bit_generator.state == game.learner.rng.bit_generator.state
    np.testing.assert_equal(restored.reward_metrics, game.reward_metrics)  # NaN equals NaN here
    assert restored.selection.best == 0.7


def test_a_run_ending_inside_an_iteration_checkpoints_its_last_step(toy_expert_file: Path, tmp_path: Path) -> None:
    # n_pol = 80 (two toy episodes) and --steps 200: the run ends half way through its third iteration,
    # holding episodes that the reward player has not ranked yet.
    cfg = TrainConfig(
        env="rankgame/PointGoal-v0",
        method="rank-ral-auto",
        expert=toy_expert_file,
        out=tmp_path / "run",
        steps=200,
        policy_updates=80,
        eval_every=100,
        eval_episodes=1,
        tensorboard=False,
        progress=False,
        sac=replace(SACConfig(), hidden_sizes=(16,), batch_size=32, start_steps=100, update_after=100),
        reward=replace(RewardConfig(), hidden_sizes=(16,), batch_size=64),
    )
    train(cfg)
    metadata, arrays = load_checkpoint(cfg.out / "checkpoint.npz")
    pending, n_ranked = arrays[FINISHED_KEY], len(arrays["ranking/agent"])
    assert metadata["env_steps"] == 200 and pending.shape[0] >= 1 and pending.shape[1] == 40
    restored = build_game(cfg)
    restored.restore(metadata, arrays)
    np.testing.assert_array_equal(np.stack(restored.finished), pending)
    # Continued to the iteration's end, RAL ranks the pending episodes after the earlier ones.
    train(replace(cfg, steps=240, resume=True))
    metadata, arrays = load_checkpoint(cfg.out / "checkpoint.npz")
    assert metadata["env_steps"] == 240 and arrays[FINISHED_KEY].shape[0] == 0
    np.testing.assert_array_equal(arrays["ranking/agent"][n_ranked : n_ranked + len(pending)], pending)
    assert [int(row["env_steps"]) for row in _rows(cfg.out)] == [100, 200, 240]


def _train_cmd(out: Path, expert: Path, *extra: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "rankgame.cli",
        "train",
        *TOY_TRAIN_ARGS,
        "--expert",
        str(expert),
        "--out",
        str(out),
        "--steps",
        "2400",
        "--eval-every",
        "200",
        "--eval-episodes",
        "1",
        "--checkpoint-every",
        "400",
        *extra,
    ]


def test_resume_after_kill_9_leaves_a_clean_metrics_file(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = subprocess.Popen(_train_cmd(out, toy_expert_file), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + 240
    while time.time() < deadline:
        if (out / "checkpoint.npz").exists() and (out / "metrics.csv").exists() and len(_rows(out)) >= 4:
            break
        time.sleep(0.2)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert len(_rows(out)) < 12, "the run finished before it could be killed"
    # The killed run left a whole policy of its last evaluation (written just before its row).
    last_logged = int(_rows(out)[-1]["env_steps"])
    assert load_policy(out / "policy.msgpack").metadata["env_steps"] in (last_logged, last_logged + 200)
    resumed = subprocess.run(_train_cmd(out, toy_expert_file, "--resume"), capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    steps = [int(row["env_steps"]) for row in _rows(out)]
    assert steps == list(range(200, 2401, 200))  # every evaluation once, none repeated or missing
    final = load_policy(out / "policy.msgpack").metadata
    assert final["env_steps"] == 2400 and final["absorbing_flag"] is True  # it reads the game's flagged obs


def test_a_run_killed_before_its_first_checkpoint_resumes_from_step_0(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "early"
    first = _train_cmd(out, toy_expert_file, "--checkpoint-every", "2400")
    proc = subprocess.Popen(first, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 240
    while time.time() < deadline and not ((out / "metrics.csv").exists() and len(_rows(out)) >= 2):
        time.sleep(0.2)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (out / "checkpoint.npz").exists() and len(_rows(out)) >= 2
    resumed = subprocess.run(_train_cmd(out, toy_expert_file, "--resume"), capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0 and "starting it again at step 0" in resumed.stderr, resumed.stderr
    assert [int(row["env_steps"]) for row in _rows(out)] == list(range(200, 2401, 200))


def test_an_existing_run_is_not_overwritten(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "once"
    out.mkdir()
    (out / "metrics.csv").write_text("env_steps\n")
    result = subprocess.run(_train_cmd(out, toy_expert_file), capture_output=True, text=True, timeout=120)
    assert result.returncode != 0 and "already holds a run" in result.stderr
    missing = subprocess.run(_train_cmd(tmp_path / "new", toy_expert_file, "--resume"), capture_output=True, text=True)
    assert missing.returncode != 0 and "no checkpoint to resume from" in missing.stderr


def test_bad_training_input_gives_one_line_errors(
    toy_expert_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def _one_line_error(args: list[str], fragment: str) -> None:
        assert_one_line_error(run_main(capsys, *args), fragment)

    base = ["train", *TOY_TRAIN_ARGS, "--steps", "100", "--out", str(tmp_path / "x")]
    _one_line_error([*base, "--expert", str(toy_expert_file), "--method", "airl"], "invalid choice: 'airl'")
    # Expert data of another environment:
    hopper = ["train", "--env", "Hopper-v5", "--expert", str(toy_expert_file), "--out", str(tmp_path / "h")]
    _one_line_error(hopper, "recorded on rankgame/PointGoal-v0, not Hopper-v5")
    assert not (tmp_path / "h").exists()  # a run refused for its input leaves no folder behind
    # Expert data whose dimensions do not match the environment:
    data = load_trajectories(toy_expert_file)
    widened = [
        Trajectory(np.pad(t.obs, ((0, 0), (0, 1))), t.acts, t.rews, t.terminated, t.truncated)
        for t in data.trajectories
    ]
    wide = save_trajectories(tmp_path / "wide.npz", "rankgame/PointGoal-v0", widened)
    _one_line_error([*base, "--expert", str(wide)], "expert data has obs_dim=3, act_dim=1")
    # An episode cut short by a time limit cannot be aligned with the horizon:
    cut_short = np.zeros(10, bool)
    cut_short[-1] = True
    cut = [Trajectory(t.obs[:11], t.acts[:10], t.rews[:10], t.terminated[:10], cut_short) for t in data.trajectories]
    short = save_trajectories(tmp_path / "short.npz", "rankgame/PointGoal-v0", cut)
    _one_line_error([*base, "--expert", str(short)], "cannot be aligned")
    # Non-finite values:
    with np.load(toy_expert_file) as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays["obs"][5, 0] = np.nan
    np.savez(tmp_path / "nan.npz", **arrays)
    _one_line_error([*base, "--expert", str(tmp_path / "nan.npz")], "NaN or infinite")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--expert-trajectories", "50"], "holds 10 trajectories")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--k", "30"], "exceed the reward bound")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--reward-input", "sa"], "use --setting lfd")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--seed", "-1"], "--seed must be >= 0")
    vanilla_mixup = [*base, "--expert", str(toy_expert_file), "--method", "rank-pal-vanilla", "--mixup", "state"]
    _one_line_error(vanilla_mixup, "--ablation.mixup is used only by the auto methods")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--reward-obs", "0:3"], "--reward-obs: '0:3' is not")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--sac.gamma", "1"], "gamma must lie in [0, 1)")
    _one_line_error([*base, "--recipe", "fancy"], "unknown recipe 'fancy'; choose from paper, tuned")
    _one_line_error([*base, "--recipe", "--seed", "1"], "argument --recipe: expected one argument")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--reward.lr", "inf"], "reward lr must be finite")
    too_much_holdout = [*base, "--expert", str(toy_expert_file), "--reward.holdout-fraction", "0.9"]
    _one_line_error(too_much_holdout, "holdout_fraction must lie in [0, 0.5]")
    no_ral_updates = [*base, "--expert", str(toy_expert_file), "--reward.ral-passes", "0"]
    _one_line_error(no_ral_updates, "ral_passes must be positive")
    _one_line_error([*base, "--expert", str(toy_expert_file), "--policy-updates", "abc"], "invalid int value: 'abc'")
    not_a_folder = tmp_path / "file.txt"
    not_a_folder.write_text("")
    at_a_file = ["train", *TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--out", str(not_a_folder)]
    _one_line_error(at_a_file, "is a file, not a folder")
    shorter = [
        "train",
        *TOY_TRAIN_ARGS,
        "--expert",
        str(toy_expert_file),
        "--steps",
        "30",
        "--out",
        str(tmp_path / "y"),
    ]
    _one_line_error(shorter, "shorter than one game iteration (40 steps")
