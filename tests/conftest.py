"""Shared fixtures (small SAC settings that compile and run in seconds) and command-line helpers."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

# Share compiled XLA programs between the many small runs (and subprocesses) of the test suite.
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", os.path.join(tempfile.gettempdir(), "rankgame-test-jax-cache"))
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")

import pytest  # noqa: E402

import rankgame.envs  # noqa: E402, F401  (registers the toy tasks)
from rankgame.policy.sac import SACConfig, sac_preset  # noqa: E402


@pytest.fixture
def tiny_sac() -> SACConfig:
    """A small SAC for the toy task: learns it in about a thousand steps."""
    return sac_preset(
        "paper",
        hidden_sizes=(64, 64),
        batch_size=64,
        start_steps=400,
        update_after=400,
        update_every=40,
        buffer_size=10_000,
    )


@pytest.fixture(scope="session")
def toy_expert_file(tmp_path_factory: pytest.TempPathFactory):
    """Ten episodes of the analytic PointGoal expert, with the random return in the metadata."""
    from rankgame.data.trajectories import save_trajectories
    from rankgame.envs.make import make_env
    from rankgame.envs.rollout import episode_returns, random_policy, rollout
    from rankgame.envs.toy import POINT_GOAL_ID, point_goal_expert

    env = make_env(POINT_GOAL_ID)
    random_return = float(episode_returns(env, random_policy(env, 0), 20, seed=0).mean())
    path = tmp_path_factory.mktemp("toy") / "expert.npz"
    return save_trajectories(
        path, POINT_GOAL_ID, rollout(env, point_goal_expert, 10, seed=0), random_return_mean=random_return
    )


@pytest.fixture(scope="session")
def toy_preference_file(tmp_path_factory: pytest.TempPathFactory):
    """Four PointGoal episodes of increasing quality (standing still, random actions, the expert) to rank."""
    import numpy as np

    from rankgame.data.trajectories import save_trajectories
    from rankgame.envs.make import make_env
    from rankgame.envs.rollout import random_policy, rollout
    from rankgame.envs.toy import POINT_GOAL_ID, point_goal_expert

    env = make_env(POINT_GOAL_ID)
    episodes = rollout(env, lambda obs: np.zeros(1, np.float32), 1, seed=1) + rollout(env, random_policy(env, 0), 2, 2)
    episodes += rollout(env, point_goal_expert, 1, seed=4)
    return save_trajectories(tmp_path_factory.mktemp("toy") / "prefs.npz", POINT_GOAL_ID, episodes)


@pytest.fixture(scope="session")
def toy_mirrored_expert_file(tmp_path_factory: pytest.TempPathFactory):
    """Ten episodes of the analytic expert on the mirrored toy task (goal at -0.5): a changed intent."""
    from rankgame.data.trajectories import save_trajectories
    from rankgame.envs.make import make_env
    from rankgame.envs.rollout import episode_returns, random_policy, rollout
    from rankgame.envs.toy import POINT_GOAL_MIRRORED_ID, point_goal_expert

    env = make_env(POINT_GOAL_MIRRORED_ID)
    random_return = float(episode_returns(env, random_policy(env, 0), 20, seed=0).mean())
    path = tmp_path_factory.mktemp("toy") / "mirrored.npz"
    episodes = rollout(env, point_goal_expert, 10, seed=0)
    return save_trajectories(path, POINT_GOAL_MIRRORED_ID, episodes, random_return_mean=random_return)


#: Command-line options of a small, fast ranking game on the toy task.
TOY_TRAIN_ARGS = (
    "--env",
    "rankgame/PointGoal-v0",
    "--sac.hidden-sizes",
    "64",
    "64",
    "--sac.batch-size",
    "64",
    "--sac.start-steps",
    "400",
    "--sac.update-after",
    "400",
    "--sac.update-every",
    "40",
    "--reward.batch-size",
    "256",
    "--no-progress",
    "--no-tensorboard",
)


#: Command-line options of a small, fast adversarial game with the PPO player on the toy task.
TOY_PPO_ARGS = (
    "--env",
    "rankgame/PointGoal-v0",
    "--ppo.rollout-steps",
    "256",
    "--reward.batch-size",
    "256",
    "--no-progress",
    "--no-tensorboard",
)


#: OPOLO's TD3 player on the toy task (its defaults wait 10000 random steps).
TOY_OPOLO_ARGS = (
    "--env",
    "rankgame/PointGoal-v0",
    "--td3.hidden-sizes",
    "64",
    "64",
    "--td3.start-steps",
    "400",
    "--td3.update-after",
    "400",
    "--td3.update-every",
    "40",
    "--reward.batch-size",
    "256",
    "--no-progress",
    "--no-tensorboard",
)


def toy_train_args(method: str) -> tuple[str, ...]:
    """:data:`TOY_TRAIN_ARGS`, :data:`TOY_PPO_ARGS` or :data:`TOY_OPOLO_ARGS`, whichever player ``method`` uses."""
    from rankgame.game.methods import METHODS

    return {"ppo": TOY_PPO_ARGS, "opolo": TOY_OPOLO_ARGS}.get(METHODS[method].policy, TOY_TRAIN_ARGS)


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """Run ``rankgame`` as a user would, in a fresh process."""
    return subprocess.run(
        [sys.executable, "-m", "rankgame.cli", *args], capture_output=True, text=True, timeout=300, check=False
    )


def run_main(capsys: pytest.CaptureFixture[str], *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``rankgame ARGS`` in this process (much faster than :func:`run_cli` for commands that fail early)."""
    from rankgame.cli import main

    capsys.readouterr()
    try:
        code = main(list(args))
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code if isinstance(exc.code, int) else 1
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, out, err)


def assert_one_line_error(result: subprocess.CompletedProcess[str], fragment: str) -> None:
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("rankgame") and fragment in lines[0], lines[0]
    assert "Traceback" not in result.stderr


def assert_missing_package_is_one_line_error(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    out: Path,
    env_id: str,
    package: str,
    extra: str,
    named: str,
) -> None:
    """With ``package`` unimportable, making ``env_id`` raises an error naming the ``extra`` to install,
    and ``rankgame expert`` on it ends with one line of stderr naming ``named``, a non-zero exit and nothing written."""
    from rankgame.cli import main
    from rankgame.envs.make import make_env
    from rankgame.errors import RankGameError

    for name in [m for m in sys.modules if m == package or m.startswith(package + ".")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, package, None)  # makes the import fail
    with pytest.raises(RankGameError, match=re.escape(f"pip install 'rankgame[{extra}]'")):
        make_env(env_id)
    assert main(["expert", "--env", env_id, "--steps", "1000", "--no-progress", "--out", str(out)]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and named in err
    assert not out.exists()  # nothing written
