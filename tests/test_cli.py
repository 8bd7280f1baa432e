"""Command line: help, a tiny end-to-end expert run, listings, and one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import assert_one_line_error, run_cli

from rankgame.checkpoint import CHECKPOINT_NAME, load_checkpoint, save_checkpoint
from rankgame.cli import main
from rankgame.data.trajectories import load_trajectories
from rankgame.policy.io import load_policy


def test_help_lists_commands_and_options(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--help"]) == 0
    assert "expert" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_info:
        main(["expert", "--preset", "paper", "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "--sac.batch-size" in out and "(default: 100)" in out and "Environment steps of SAC training" in out


TOY_EXPERT_ARGS = (
    "expert",
    "--env",
    "rankgame/PointGoal-v0",
    "--eval-every",
    "300",
    "--checkpoint-every",
    "300",
    "--trajectories",
    "3",
    "--random-episodes",
    "4",
    "--sac.hidden-sizes",
    "16",
    "16",
    "--sac.start-steps",
    "200",
    "--sac.update-after",
    "200",
    "--no-progress",
)


def test_expert_end_to_end_on_the_toy_task(tmp_path: Path) -> None:
    out = tmp_path / "expert"
    result = run_cli(*TOY_EXPERT_ARGS, "--steps", "600", "--out", str(out))
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    data = load_trajectories(out / "trajectories.npz", env_id="rankgame/PointGoal-v0")
    assert len(data.trajectories) == 3 and summary["return_mean"] == pytest.approx(data.returns.mean(), rel=1e-5)
    assert data.metadata["command"].startswith("rankgame expert --env rankgame/PointGoal-v0")
    assert data.metadata["train_seed"] == 0
    assert load_policy(out / "best_policy.msgpack").env_id == "rankgame/PointGoal-v0"
    rows = (out / "metrics.csv").read_text().splitlines()
    assert rows[0].startswith("env_steps,wall_s") and [r.split(",")[0] for r in rows[1:]] == ["300", "600"]
    assert any((out / "tb").iterdir())

    again = run_cli(
        "record",
        "--policy",
        str(out / "best_policy.msgpack"),
        "--out",
        str(tmp_path / "r.npz"),
        "--episodes",
        "2",
        "--random-episodes",
        "2",
    )
    assert again.returncode == 0, again.stderr
    assert len(load_trajectories(tmp_path / "r.npz").trajectories) == 2
    # The toy task reports no success: --successful-only is refused, and nothing is written.
    refused = run_cli(
        "record", "--policy", str(out / "best_policy.msgpack"), "--out", str(tmp_path / "s.npz"), "--successful-only"
    )
    assert_one_line_error(refused, "reports no success")
    assert not (tmp_path / "s.npz").exists()


def test_experts_listing_as_json() -> None:
    result = run_cli("experts", "--json")
    assert result.returncode == 0, result.stderr
    rows = json.loads(result.stdout)
    assert rows and all(row["trajectories"] >= 10 and row["return_mean"] > row["random_return"] for row in rows)
    table = run_cli("experts")
    assert table.stdout.splitlines()[0].split()[:2] == ["env", "trajs"]


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["expert", "--env", "NoSuchEnv-v0", "--steps", "10"], "unknown environment id 'NoSuchEnv-v0'"),
        (["expert", "--env", "CartPole-v1", "--steps", "10"], "Discrete action space"),
        (["expert", "--steps", "ten"], "invalid int value"),
        (["expert", "--steps", "-5"], "must be positive"),
        (["expert", "--sac.gamma", "2"], "gamma must lie in [0, 1)"),
        (["expert", "--preset", "fancy"], "unknown preset 'fancy'"),
        (["fly"], "unknown command 'fly'"),
        (["record", "--policy", "/nonexistent/p.msgpack"], "policy file not found"),
    ],
)
def test_bad_input_gives_one_line_error(args: list[str], fragment: str) -> None:
    assert_one_line_error(run_cli(*args), fragment)


def test_corrupt_policy_file_gives_one_line_error(tmp_path: Path) -> None:
    bad = tmp_path / "p.msgpack"
    bad.write_bytes(b"\x93not msgpack at all")
    assert_one_line_error(run_cli("record", "--policy", str(bad)), "unreadable or truncated policy file")


def test_plot_draws_curves_and_rejects_bad_runs(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.csv").write_text("env_steps,normalized_score\n1000,10\n2000,55.5\n")
    assert main(["plot", str(run), "--out", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG"
    assert_one_line_error(run_cli("plot", str(run), "--column", "nope"), "has no column 'nope'")
    assert_one_line_error(run_cli("plot", str(tmp_path / "none")), "no metrics.csv")
    assert_one_line_error(run_cli("plot", str(run), "--out", str(tmp_path / "c.xyz")), "cannot write a .xyz image")
    assert not (tmp_path / "c.xyz").exists()
    assert main(["plot", str(run), "--out", str(tmp_path / "c.svg")]) == 0
    assert b"<svg" in (tmp_path / "c.svg").read_bytes()[:1000]


def test_expert_run_resumes_and_trains_longer(tmp_path: Path) -> None:
    out = tmp_path / "expert"
    assert run_cli(*TOY_EXPERT_ARGS, "--steps", "600", "--out", str(out)).returncode == 0
    assert_one_line_error(run_cli(*TOY_EXPERT_ARGS, "--steps", "900", "--out", str(out)), "already holds a run")
    changed = run_cli(*TOY_EXPERT_ARGS, "--steps", "900", "--out", str(out), "--resume", "--sac.gamma", "0.9")
    assert_one_line_error(changed, "--sac.gamma 0.9 differs from the run's 0.99")
    resumed = run_cli(*TOY_EXPERT_ARGS, "--steps", "900", "--out", str(out), "--resume")
    assert resumed.returncode == 0, resumed.stderr
    steps = [row.split(",")[0] for row in (out / "metrics.csv").read_text().splitlines()[1:]]
    assert steps == ["300", "600", "900"]
    record = json.loads((out / "config.json").read_text())
    assert "--resume" not in record["command"] and "--steps 600" in record["command"]
    assert len(record["resumed_with"]) == 1 and "--resume" in record["resumed_with"][0]
    assert load_policy(out / "policy.msgpack").metadata["env_steps"] == 900
    assert load_trajectories(out / "trajectories.npz").metadata["train_steps"] == 900
    shorter = run_cli(*TOY_EXPERT_ARGS, "--steps", "300", "--out", str(out), "--resume")
    assert_one_line_error(shorter, "--steps 300 is below the checkpoint's 900")


def test_expert_resume_without_checkpoint_fails_cleanly(tmp_path: Path) -> None:
    result = run_cli(*TOY_EXPERT_ARGS, "--steps", "600", "--out", str(tmp_path / "none"), "--resume")
    assert_one_line_error(result, "no checkpoint to resume from")


def test_expert_resume_keeps_a_best_policy_saved_after_its_last_checkpoint(tmp_path: Path) -> None:
    out = tmp_path / "expert"
    assert run_cli(*TOY_EXPERT_ARGS, "--steps", "600", "--out", str(out)).returncode == 0
    best = load_policy(out / "best_policy.msgpack").metadata
    # As if the run had died after saving its best policy but before the checkpoint recording it:
    metadata, arrays = load_checkpoint(out / CHECKPOINT_NAME)
    metadata["progress"].update(best_return=best["eval_return"] - 1.0, best_step=0)
    save_checkpoint(out / CHECKPOINT_NAME, metadata, arrays)
    resumed = run_cli(*TOY_EXPERT_ARGS, "--steps", "600", "--out", str(out), "--resume")
    assert resumed.returncode == 0, resumed.stderr
    summary = json.loads(resumed.stdout)
    assert summary["best_step"] == best["env_steps"] and summary["best_eval_return"] == best["eval_return"]


def test_evaluate_reports_the_policy_return_and_its_normalized_score(tmp_path: Path, toy_expert_file: Path) -> None:
    import jax

    from rankgame.data.experts import shipped_expert_path
    from rankgame.envs.make import env_spec, make_env
    from rankgame.envs.rollout import episode_returns
    from rankgame.envs.toy import POINT_GOAL_ID
    from rankgame.policy.io import save_policy
    from rankgame.policy.sac import SAC, sac_preset

    env = make_env(POINT_GOAL_ID)
    spec = env_spec(env)
    sac = SAC(spec.obs_dim, spec.act_dim, sac_preset("paper", hidden_sizes=(8, 8)))
    params = sac.init(jax.random.key(3)).actor_params
    path = save_policy(tmp_path / "p.msgpack", sac, params, POINT_GOAL_ID, spec.act_low, spec.act_high)
    args = ("--policy", str(path), "--episodes", "3", "--seed", "5", "--expert", str(toy_expert_file))
    result = run_cli("evaluate", *args)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    expected = episode_returns(env, load_policy(path).policy_fn(), 3, seed=5)
    expert = load_trajectories(toy_expert_file)
    expert_return, random_return = expert.returns.mean(), expert.metadata["random_return_mean"]
    assert summary["env"] == POINT_GOAL_ID and summary["episodes"] == 3
    assert summary["return_mean"] == pytest.approx(expected.mean(), rel=1e-6)
    assert summary["return_min"] == pytest.approx(expected.min(), rel=1e-6)
    assert summary["episode_returns"] == pytest.approx(expected.tolist(), rel=1e-6)  # in episode order
    assert summary["episode_successes"] is None  # the toy task reports no success
    assert summary["normalized_score"] == pytest.approx(
        100 * (expected.mean() - random_return) / (expert_return - random_return), rel=1e-6
    )
    # No shipped data for the toy task and no --expert: the score is not defined.
    assert json.loads(run_cli("evaluate", "--policy", str(path), "--episodes", "1").stdout)["normalized_score"] is None
    assert_one_line_error(run_cli("evaluate", "--policy", str(path), "--episodes", "0"), "--episodes must be positive")
    other = run_cli("evaluate", "--policy", str(path), "--expert", str(shipped_expert_path("Hopper-v5")))
    assert_one_line_error(other, "recorded on Hopper-v5")
