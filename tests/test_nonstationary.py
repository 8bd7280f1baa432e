"""Non-stationary imitation (Sec. 5.3): the Hopper variants and ``rankgame train --switch-at``."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_main

from rankgame.cli import main
from rankgame.config import SwitchConfig, TrainConfig
from rankgame.data.experts import shipped_expert_path
from rankgame.data.trajectories import load_trajectories
from rankgame.envs.make import env_spec, make_env
from rankgame.envs.toy import POINT_GOAL_ID, POINT_GOAL_MIRRORED_ID
from rankgame.envs.variants import HEAVY_MASS_SCALE, HOPPER_BACKWARD_ID, HOPPER_HEAVY_ID
from rankgame.errors import RankGameError
from rankgame.policy.io import load_policy
from rankgame.policy.sac import SACConfig
from rankgame.reward.player import RewardConfig
from rankgame.training import build_game


def test_hopper_variants_change_the_reward_or_the_masses_only() -> None:
    envs = {env_id: make_env(env_id) for env_id in ("Hopper-v5", HOPPER_BACKWARD_ID, HOPPER_HEAVY_ID)}
    specs = {env_id: env_spec(env) for env_id, env in envs.items()}
    assert len({(s.obs_dim, s.act_dim, s.max_episode_steps) for s in specs.values()}) == 1
    masses = {env_id: env.unwrapped.model.body_mass.copy() for env_id, env in envs.items()}
    np.testing.assert_allclose(masses[HOPPER_HEAVY_ID], HEAVY_MASS_SCALE * masses["Hopper-v5"])
    np.testing.assert_array_equal(masses[HOPPER_BACKWARD_ID], masses["Hopper-v5"])
    # Same seed and actions: the same states, and rewards that differ by twice the forward velocity.
    for env in envs.values():
        env.reset(seed=0)
    action = np.full(3, 0.3, np.float32)
    for _ in range(10):
        obs_f, rew_f, _, _, info = envs["Hopper-v5"].step(action)
        obs_b, rew_b, _, _, _ = envs[HOPPER_BACKWARD_ID].step(action)
        np.testing.assert_array_equal(obs_f, obs_b)
        assert rew_f - rew_b == pytest.approx(2.0 * info["x_velocity"])
    assert not np.allclose(envs[HOPPER_HEAVY_ID].step(action)[0], envs["Hopper-v5"].step(action)[0])


def _switching_config(expert: Path, mirrored: Path, **changes: object) -> TrainConfig:
    cfg = TrainConfig(
        env=POINT_GOAL_ID,
        method="rank-ral-auto",  # keeps all agent data, to check that it carries over
        expert=expert,
        switch=SwitchConfig(at=400, env=POINT_GOAL_MIRRORED_ID, expert=mirrored),
        steps=800,
        sac=replace(SACConfig(), hidden_sizes=(16,), batch_size=32, start_steps=100, update_after=100),
        reward=replace(RewardConfig(), hidden_sizes=(16,), batch_size=64),
    )
    return replace(cfg, **changes)


def test_a_switch_moves_the_game_to_the_new_task_and_expert(
    toy_expert_file: Path, toy_mirrored_expert_file: Path, tmp_path: Path
) -> None:
    game = build_game(_switching_config(toy_expert_file, toy_mirrored_expert_file))
    for step in range(1, 401):
        game.step(step)
    data = game.rankings.data
    old_rows = len(data.holdout_rows)
    assert game.switch is not None and game.switch.due(401)
    game.apply_switch()
    mirrored = load_trajectories(toy_mirrored_expert_file)
    assert game.learner.env.spec.id == game.eval_env.spec.id == POINT_GOAL_MIRRORED_ID
    np.testing.assert_allclose(data.expert[0, :, 0], mirrored.trajectories[0].obs[:40, 0])
    assert game.scale.expert_return == pytest.approx(mirrored.returns.mean())
    assert len(data.holdout_rows) == old_rows and len(data.agent) == 10  # agent data carries over
    game.env_step()
    assert game.learner.env_steps == 401
    # A run resumed from a checkpoint written after the switch continues on the new task.
    resumed = build_game(_switching_config(toy_expert_file, toy_mirrored_expert_file))
    assert resumed.learner.env.spec.id == POINT_GOAL_ID
    resumed.restore(*game.checkpoint())
    assert resumed.learner.env.spec.id == POINT_GOAL_MIRRORED_ID
    np.testing.assert_array_equal(resumed.rankings.data.expert, data.expert)
    np.testing.assert_array_equal(resumed.rankings.data.holdout_rows, data.holdout_rows)
    assert resumed.scale.expert_return == game.scale.expert_return


def test_the_game_follows_a_changed_intent(
    toy_expert_file: Path, toy_mirrored_expert_file: Path, tmp_path: Path
) -> None:
    """Imitate the expert of goal +0.5, then from step 2000 the expert of goal -0.5 (scores are normalized
    by the expert being imitated at the time: 100 is that expert, 0 a random policy)."""
    out = tmp_path / "switch"
    args = [*TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--steps", "4000", "--eval-every", "400"]
    args += [
        "--switch-at",
        "2000",
        "--switch-env",
        POINT_GOAL_MIRRORED_ID,
        "--switch-expert",
        str(toy_mirrored_expert_file),
    ]
    assert main(["train", *args, "--eval-episodes", "10", "--out", str(out)]) == 0
    with (out / "metrics.csv").open() as handle:
        scores = {int(row["env_steps"]): float(row["normalized_score"]) for row in csv.DictReader(handle)}
    assert scores[2000] > 70.0, scores  # the first expert imitated
    # The new expert imitated: a policy that still walked to the old goal would score far below 0 here.
    assert scores[4000] > 70.0, scores
    assert load_policy(out / "policy.msgpack").env_id == POINT_GOAL_MIRRORED_ID  # evaluated where it ended


def test_bad_switch_settings_give_one_line_errors(
    toy_expert_file: Path, toy_mirrored_expert_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["train", *TOY_TRAIN_ARGS, "--expert", str(toy_expert_file), "--steps", "800", "--out", str(tmp_path / "x")]
    assert_one_line_error(
        run_main(capsys, *base, "--switch.at", "400"), "--switch.at needs --switch.env or --switch.expert"
    )
    assert_one_line_error(
        run_main(capsys, *base, "--switch-env", POINT_GOAL_MIRRORED_ID), "--switch.at needs"
    )  # old spelling
    late = [*base, "--switch.at", "800", "--switch.env", POINT_GOAL_MIRRORED_ID]
    assert_one_line_error(run_main(capsys, *late), "--switch.at must lie between 0 and --steps 800")
    other_spaces = [*base, "--switch.at", "400", "--switch.env", "Hopper-v5"]
    assert_one_line_error(
        run_main(capsys, *other_spaces), "--switch.env Hopper-v5 has (obs_dim, act_dim, horizon) = (11, 3, 1000)"
    )
    wrong_task = [*base, "--switch-at", "400", "--switch-expert", str(toy_mirrored_expert_file)]
    assert_one_line_error(
        run_main(capsys, *wrong_task), "recorded on rankgame/PointGoalMirrored-v0, not rankgame/PointGoal-v0"
    )


def test_a_switch_to_the_backward_hopper_imitates_its_shipped_expert() -> None:
    backward = build_game(TrainConfig(steps=2000, switch=SwitchConfig(at=1000, env=HOPPER_BACKWARD_ID)))
    assert backward.switch is not None and backward.switch.expert is not None
    assert backward.switch.expert.env_id == HOPPER_BACKWARD_ID
    assert backward.switch.expert.returns.mean() > 1500  # it hops backward
    heavy = build_game(TrainConfig(steps=2000, switch=SwitchConfig(at=1000, env=HOPPER_HEAVY_ID)))
    assert heavy.switch is not None and heavy.switch.expert is None  # no shipped data: the Hopper-v5 expert


def test_the_pref_methods_may_change_the_task_but_not_the_expert(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Their offline chain is ranked below the first expert: a switch env's shipped expert is refused.
    out = tmp_path / "x"
    base = ["train", "--method", "rank-pal-pref", "--steps", "2000", "--switch.at", "1000", "--out", str(out)]
    refused = run_main(capsys, *base, "--switch.env", HOPPER_BACKWARD_ID)
    assert_one_line_error(refused, f"--switch.env {HOPPER_BACKWARD_ID} brings its shipped expert")
    assert "rankgame/HopperHeavy-v5" in refused.stderr and "--method other than rank-pal-pref" in refused.stderr
    assert refused.returncode == 1 and not out.exists()
    with pytest.raises(RankGameError, match="brings its shipped expert"):
        TrainConfig(method="rank-ral-pref", steps=2000, switch=SwitchConfig(at=1000, env=HOPPER_BACKWARD_ID)).validate()
    # A change of dynamics alone keeps the first expert (and the offline chain ranked below it).
    heavy = TrainConfig(method="rank-pal-pref", steps=2000, switch=SwitchConfig(at=1000, env=HOPPER_HEAVY_ID))
    heavy.validate()
    game = build_game(heavy)
    assert game.switch is not None and game.switch.env_id == HOPPER_HEAVY_ID and game.switch.expert is None
    # A switch expert given in Python is refused too.
    with pytest.raises(RankGameError, match="switch expert cannot be combined with the pref methods"):
        build_game(heavy, switch_expert=shipped_expert_path(HOPPER_BACKWARD_ID))
