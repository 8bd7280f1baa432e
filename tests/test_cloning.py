"""BC and BCO: the likelihood by hand, the inverse model on a linear system, learning the toy task,
refused data, exact resume, and policy files that `rankgame evaluate` reads."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import assert_one_line_error, run_main

from rankgame.baselines.bco import BCO_LOG_COLUMNS, BCOTrainer
from rankgame.baselines.cloning import (
    ACTION_CLIP,
    BC_LOG_COLUMNS,
    BCTrainer,
    CloningConfig,
    tanh_gaussian_nll,
)
from rankgame.baselines.inverse_dynamics import InverseDynamics
from rankgame.checkpoint import flatten_tree, load_checkpoint, save_checkpoint
from rankgame.data.trajectories import TrajectoryFile, load_trajectories
from rankgame.envs.toy import POINT_GOAL_ID
from rankgame.errors import RankGameError
from rankgame.policy.io import load_policy
from rankgame.run import RunSettings, open_run, run

#: Small networks and short fits: BC and BCO learn the toy task in a few hundred gradient steps.
TINY = CloningConfig(
    hidden_sizes=(32, 32),
    batch_size=64,
    update_every=100,
    pre_steps=200,
    alpha=0.5,
    pre_inverse_steps=200,
    pre_policy_steps=200,
    inverse_steps=100,
    policy_steps=100,
    inverse_hidden_sizes=(32, 32),
    inverse_lr=1e-3,
)


@pytest.fixture(scope="module")
def toy_expert(toy_expert_file: Path) -> TrajectoryFile:
    return load_trajectories(toy_expert_file, POINT_GOAL_ID)


def _without_actions(data: TrajectoryFile) -> TrajectoryFile:
    """The same episodes with every action replaced by 0: observation-only data."""
    episodes = tuple(dataclasses.replace(t, acts=np.zeros_like(t.acts)) for t in data.trajectories)
    return TrajectoryFile(data.env_id, episodes, data.metadata)


def _tree_equal(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_nll_of_one_action_matches_the_hand_computed_value() -> None:
    # a = tanh(u), u ~ N(0.3, 0.5^2): -log p(a) = -log N(atanh a; 0.3, 0.5) + log(1 - a^2).
    mean, log_std, act = 0.3, np.log(0.5), 0.6
    u = np.arctanh(act)
    expected = 0.5 * ((u - mean) / 0.5) ** 2 + np.log(0.5) + 0.5 * np.log(2 * np.pi) + np.log(1 - act**2)
    nll = tanh_gaussian_nll(jnp.array([[mean]]), jnp.array([[log_std]]), jnp.array([[act]]))
    assert nll.shape == (1,)
    np.testing.assert_allclose(nll, [expected], rtol=1e-5)


def test_nll_of_actions_on_the_bounds_is_finite_through_the_clip() -> None:
    acts = jnp.array([[1.0], [-1.0]])
    nll = tanh_gaussian_nll(jnp.zeros((2, 1)), jnp.zeros((2, 1)), acts)
    u = np.arctanh(np.float32(ACTION_CLIP))
    expected = 0.5 * u**2 + 0.5 * np.log(2 * np.pi) + np.log(1 - np.float32(ACTION_CLIP) ** 2)
    np.testing.assert_allclose(nll, [expected, expected], rtol=1e-3)
    grads = jax.grad(lambda m: jnp.sum(tanh_gaussian_nll(m, jnp.zeros((2, 1)), acts)))(jnp.zeros((2, 1)))
    assert np.all(np.isfinite(grads))


def test_inverse_model_recovers_the_actions_of_a_linear_system() -> None:
    # x' = A x + B a with B of full column rank: a = pinv(B) (x' - A x) is a function of (x, x').
    rng = np.random.default_rng(0)
    a_mat = np.array([[0.9, 0.1, 0.0], [-0.1, 0.8, 0.2], [0.0, 0.3, 0.7]], np.float32)
    b_mat = np.array([[1.0, 0.0], [0.5, 1.0], [0.0, -0.5]], np.float32)

    def transitions(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = rng.normal(size=(n, 3)).astype(np.float32)
        acts = rng.uniform(-1.0, 1.0, (n, 2)).astype(np.float32)
        return x, acts, (x @ a_mat.T + acts @ b_mat.T).astype(np.float32)

    x, acts, next_x = transitions(4000)
    model = InverseDynamics(3, 2, (64, 64), lr=1e-3, batch_size=128, chunk=200)
    state = model.with_statistics(model.init(jax.random.key(0)), x, next_x)
    state, _ = model.fit(state, x, acts, next_x, rng, 2000)
    test_x, test_acts, test_next = transitions(1000)
    pred = np.asarray(model.predict(state, test_x, test_next))
    # Uniform actions have variance 1/3: a mean squared error of 0.005 explains 98.5% of it.
    assert float(np.mean((pred - test_acts) ** 2)) < 0.005
    assert float(np.max(np.abs(pred - test_acts))) < 0.3


def test_bc_clones_the_toy_expert(toy_expert: TrajectoryFile) -> None:
    trainer = BCTrainer(TINY, POINT_GOAL_ID, toy_expert, 5, seed=0, eval_episodes=10)
    for step in range(1, 501):
        trainer.step(step)
    row = trainer.evaluate()
    metrics = trainer.training_metrics()
    assert trainer.grad_steps == metrics["grad_steps"] == 500 and trainer.env_steps == 500
    # Random actions score about -24 here, standing still about -30, the expert about -1: 80 (a mean
    # return above -5.6 over 10 episodes) is out of reach of anything that does not steer to the goal.
    assert row["normalized_score"] > 80.0, row
    assert np.isfinite(metrics["losses/bc"])


def test_bco_imitates_the_toy_expert_from_observations_only(toy_expert: TrajectoryFile) -> None:
    config = dataclasses.replace(TINY, pre_steps=500, pre_inverse_steps=500, pre_policy_steps=500, alpha=0.5)
    trainer = BCOTrainer(config, POINT_GOAL_ID, _without_actions(toy_expert), 5, seed=0, eval_episodes=10)
    for step in range(1, 1001):
        trainer.step(step)
    row, metrics = trainer.evaluate(), trainer.training_metrics()
    assert trainer.env_steps == 1000 and len(trainer.data) == 1000
    # Fits at steps 500, 750 and 1000.
    assert metrics["grad_steps"] == 700 and metrics["inverse_grad_steps"] == 700
    assert row["normalized_score"] > 80.0, row
    assert metrics["losses/inverse"] < 0.05


def test_bc_refuses_expert_data_without_usable_actions(toy_expert: TrajectoryFile) -> None:
    with pytest.raises(RankGameError, match="every action in the expert data is 0") as info:
        BCTrainer(TINY, POINT_GOAL_ID, _without_actions(toy_expert), 1, seed=0, eval_episodes=1)
    assert "\n" not in str(info.value)
    scaled = tuple(dataclasses.replace(t, acts=10.0 * t.acts + 5.0) for t in toy_expert.trajectories)
    with pytest.raises(RankGameError, match="action box"):
        BCTrainer(TINY, POINT_GOAL_ID, TrajectoryFile(POINT_GOAL_ID, scaled, toy_expert.metadata), 1, 0, 1)
    with pytest.raises(RankGameError, match="holds 10 trajectories"):
        BCTrainer(TINY, POINT_GOAL_ID, toy_expert, 11, seed=0, eval_episodes=1)
    with pytest.raises(RankGameError, match="bad cloning setting: alpha"):
        BCTrainer(dataclasses.replace(TINY, alpha=0.0), POINT_GOAL_ID, toy_expert, 1, seed=0, eval_episodes=1)


def test_bco_refuses_a_run_shorter_than_its_pre_demonstration_phase(toy_expert: TrajectoryFile) -> None:
    with pytest.raises(RankGameError, match="pre-demonstration"):
        BCOTrainer(TINY, POINT_GOAL_ID, toy_expert, 1, seed=0, eval_episodes=1, steps=100)


def _settings(out: Path, steps: int, resume: bool = False) -> RunSettings:
    return RunSettings(out, steps, 100, 100, resume, tensorboard=False, progress=False, description="bc")


def _run_bc(expert: TrajectoryFile, out: Path, steps: int, resume: bool = False) -> BCTrainer:
    config = {"method": "bc", "seed": 0, "steps": steps, "out": str(out), "resume": resume}
    settings = _settings(out, steps, resume)
    resumed = open_run(settings, config)
    trainer = BCTrainer(TINY, POINT_GOAL_ID, expert, 2, seed=0, eval_episodes=2)
    run(trainer, settings, resumed, config, BC_LOG_COLUMNS, "test")
    return trainer


def test_bc_resumed_through_the_harness_equals_an_uninterrupted_run_and_saves_a_loadable_policy(
    toy_expert: TrajectoryFile, tmp_path: Path
) -> None:
    straight = _run_bc(toy_expert, tmp_path / "straight", 300)
    _run_bc(toy_expert, tmp_path / "resumed", 150)  # stops inside a fused block
    resumed = _run_bc(toy_expert, tmp_path / "resumed", 300, resume=True)
    _tree_equal(flatten_tree("bc", straight.state), flatten_tree("bc", resumed.state))
    assert resumed.grad_steps == straight.grad_steps == 300

    with (tmp_path / "resumed" / "metrics.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [int(row["env_steps"]) for row in rows] == [100, 150, 200, 300]
    assert rows[-1]["grad_steps"] == "300" and rows[-1]["losses/bc"] and rows[-1]["normalized_score"]

    saved = load_policy(tmp_path / "resumed" / "policy.msgpack")
    assert saved.env_id == POINT_GOAL_ID and saved.metadata["env_steps"] == 300
    obs = np.random.default_rng(1).uniform(-1.0, 1.0, (20, 2)).astype(np.float32)
    loaded, current = saved.policy_fn(), resumed.policy()
    np.testing.assert_array_equal([loaded(o) for o in obs], [current(o) for o in obs])


def test_bco_checkpoint_mid_episode_and_mid_round_resumes_exactly(toy_expert: TrajectoryFile, tmp_path: Path) -> None:
    def trainer() -> BCOTrainer:
        return BCOTrainer(TINY, POINT_GOAL_ID, toy_expert, 2, seed=3, eval_episodes=1)

    straight = trainer()
    for step in range(1, 401):
        straight.step(step)

    first = trainer()
    for step in range(1, 251):  # 250: inside an episode (40 steps each) and inside a round (100 steps)
        first.step(step)
    metadata, arrays = first.checkpoint()
    save_checkpoint(tmp_path / "checkpoint.npz", {**metadata, "config": {}}, arrays)
    metadata, arrays = load_checkpoint(tmp_path / "checkpoint.npz")
    second = trainer()
    second.restore(metadata, arrays)
    assert second.env_steps == 250
    for step in range(251, 401):
        second.step(step)

    for prefix, a, b in (
        ("bc", straight.state, second.state),
        ("inverse", straight.inverse_state, second.inverse_state),
    ):
        _tree_equal(flatten_tree(prefix, a), flatten_tree(prefix, b))
    _tree_equal(straight.data.state_dict(), second.data.state_dict())
    assert straight.training_metrics() == second.training_metrics()
    assert set(second.training_metrics()) | {"eval_return", "normalized_score"} <= set(BCO_LOG_COLUMNS)


def test_bc_and_bco_train_from_the_command_line_and_refuse_what_they_cannot_use(
    capsys: pytest.CaptureFixture[str], toy_expert_file: Path, tmp_path: Path
) -> None:
    base = ["train", "--env", "rankgame/PointGoal-v0", "--expert", str(toy_expert_file), "--no-progress"]
    base += ["--no-tensorboard", "--eval-episodes", "2"]
    runs = {
        "bc": ["--steps", "200", "--eval-every", "100"],
        "bco": ["--steps", "300", "--eval-every", "100", "--cloning.pre-steps", "200"],
    }
    for method, extra in runs.items():
        out = tmp_path / method
        assert run_main(capsys, *base, "--method", method, *extra, "--out", str(out)).returncode == 0
        assert (out / "policy.msgpack").is_file() and (out / "checkpoint.npz").is_file()
    refusals = {
        ("--method", "bc", "--setting", "lfo"): "bc learns only from demonstrations (lfd)",
        ("--method", "bco", "--reward.lr", "0.1"): "--reward.* is not used by bco",
        ("--method", "rank-pal-auto", "--cloning.lr", "0.1"): "--cloning.* is not used by rank-pal-auto",
    }
    for options, message in refusals.items():
        result = run_main(capsys, *base, *options, "--out", str(tmp_path / "refused"))
        assert_one_line_error(result, message)
        assert not (tmp_path / "refused").exists()
