"""The public Python API: train with in-memory data and a callback that stops the run, the learned reward
taken out of a run, and ``python -m rankgame``."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_cli

import rankgame
from rankgame import TrainConfig, export_reward, load_reward, load_trajectories, train
from rankgame.envs.rollout import random_policy, rollout
from rankgame.envs.toy import POINT_GOAL_ID
from rankgame.errors import RankGameError
from rankgame.policy.sac import sac_preset
from rankgame.reward.player import RewardConfig


def _toy_config(out: Path, **changes: object) -> TrainConfig:
    sac = sac_preset("paper", hidden_sizes=(64, 64), batch_size=64, start_steps=400, update_after=400, update_every=40)
    cfg = TrainConfig(
        env=POINT_GOAL_ID,
        out=out,
        steps=4000,
        eval_every=400,
        eval_episodes=5,
        tensorboard=False,
        progress=False,
        sac=sac,
        reward=RewardConfig(batch_size=256),
    )
    return replace(cfg, **changes)


def test_the_public_names_are_importable_from_rankgame() -> None:
    for name in rankgame.__all__:
        assert getattr(rankgame, name) is not None, name
    with pytest.raises(AttributeError):
        rankgame.no_such_name  # noqa: B018


def test_a_config_built_in_python_is_checked_like_the_command_line(tmp_path: Path) -> None:
    from rankgame import AblationConfig

    with pytest.raises(
        RankGameError, match=r"^bad setting: ablation.budget='foo' \(choose from leader, holdout, passes\)$"
    ):
        train(_toy_config(tmp_path / "x", ablation=AblationConfig(budget="foo")))  # type: ignore[arg-type]
    with pytest.raises(RankGameError, match=r"^bad setting: setting='lfx'"):
        train(_toy_config(tmp_path / "y", setting="lfx"))
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_a_callback_stops_training_and_the_learned_reward_ranks_the_expert_first(
    toy_expert_file: Path, tmp_path: Path
) -> None:
    """In-memory expert data, a callback that stops once the score passes 60, and the exported reward."""
    expert = load_trajectories(toy_expert_file)
    seen: list[tuple[int, float]] = []

    def stop_when_good(step: int, row: dict[str, float]) -> bool:
        seen.append((step, row["normalized_score"]))
        return row["normalized_score"] < 60.0

    out = tmp_path / "api"
    summary = train(_toy_config(out), expert=list(expert.trajectories), callback=stop_when_good)
    assert summary["stopped_early"] is True and seen[-1][1] >= 60.0
    assert summary["env_steps"] == seen[-1][0] < 4000 and all(score < 60.0 for _, score in seen[:-1])
    with (out / "metrics.csv").open() as handle:
        assert [int(row["env_steps"]) for row in csv.DictReader(handle)] == [step for step, _ in seen]
    assert json.loads((out / "config.json").read_text())["expert"] == "(in memory)"

    reward = load_reward(export_reward(out, tmp_path / "reward.msgpack"))
    assert reward.env_id == POINT_GOAL_ID and reward.input == "s"
    env = rankgame.make_env(POINT_GOAL_ID)
    random_obs = np.concatenate([t.obs[:-1] for t in rollout(env, random_policy(env, 1), 10, seed=50)])
    expert_obs = np.concatenate([t.obs[:-1] for t in expert.trajectories])
    expert_reward, random_reward = reward(expert_obs), reward(random_obs)
    assert expert_reward.shape == (len(expert_obs),)
    assert expert_reward.mean() > random_reward.mean() + 1.0  # the reward's range is [0, k = 10]
    with pytest.raises(RankGameError, match=r"obs must have shape \(N, 2\)"):
        reward(np.zeros((3, 5)))


def test_a_run_stopped_by_its_callback_resumes_where_it_stopped(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "stop"
    cfg = _toy_config(out, expert=toy_expert_file, steps=1200)
    first = train(cfg, callback=lambda step, row: step < 800)
    assert first["stopped_early"] and first["env_steps"] == 800
    second = train(replace(cfg, resume=True))
    assert not second["stopped_early"] and second["env_steps"] == 1200
    with (out / "metrics.csv").open() as handle:
        assert [int(row["env_steps"]) for row in csv.DictReader(handle)] == [400, 800, 1200]


def test_export_reward_from_the_command_line(toy_expert_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "lfd"
    args = [*TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--setting", "lfd", "--steps", "400"]
    assert run_cli("train", *args, "--eval-every", "400", "--eval-episodes", "1", "--out", str(out)).returncode == 0
    result = run_cli("export-reward", str(out), "--out", str(tmp_path / "r.msgpack"))
    assert result.returncode == 0, result.stderr
    reward = load_reward(result.stdout.strip())
    assert reward.input == "sa"
    assert reward(np.zeros((4, 2)), acts=np.zeros((4, 1))).shape == (4,)
    with pytest.raises(RankGameError, match=r"reads \(s, a\): pass acts"):
        reward(np.zeros((4, 2)))
    assert_one_line_error(run_cli("export-reward", str(tmp_path), "--out", "x.msgpack"), "no checkpoint.npz in")
    (tmp_path / "junk.msgpack").write_bytes(b"not a reward")
    with pytest.raises(RankGameError, match="unreadable or truncated reward file"):
        load_reward(tmp_path / "junk.msgpack")


def test_python_dash_m_rankgame_runs_the_command_line() -> None:
    result = subprocess.run([sys.executable, "-m", "rankgame", "--version"], capture_output=True, text=True)
    assert result.returncode == 0 and result.stdout.strip() == f"rankgame {rankgame.__version__}"
    result = subprocess.run([sys.executable, "-m", "rankgame", "train", "--help"], capture_output=True, text=True)
    assert result.returncode == 0 and "--rankings.k" in result.stdout and "--leader.patience" in result.stdout


def test_archived_policy_files_of_the_same_format_version_still_load() -> None:
    """Policy files written before SAC's initializer option was removed name it in their header."""
    archived = Path(__file__).resolve().parents[1] / "benchmarks/results/pen/expert-sac-10traj/rank-pal-pref-s0"
    policy = rankgame.load_policy(archived / "policy.msgpack")
    assert policy.env_id == "rankgame/Pen-v0" and policy.metadata["env_steps"] == 1_000_000
    act = policy.policy_fn()(np.zeros(policy.sac.obs_dim - 1, np.float32))  # it reads the absorbing flag too
    assert act.shape == (policy.sac.act_dim,) and np.all(np.isfinite(act))
