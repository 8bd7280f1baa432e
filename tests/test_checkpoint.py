"""Resuming a run: which checkpoint it continues from, for every state of its folder, and which settings may change."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rankgame.checkpoint import (
    CHECKPOINT_NAME,
    RUN_CONTROL_OPTIONS,
    checkpoint_to_resume,
    load_run_checkpoint,
    require_same_settings,
    save_checkpoint,
)
from rankgame.errors import RankGameError


def test_a_new_folder_starts_at_step_0_and_cannot_be_resumed(tmp_path: Path) -> None:
    assert checkpoint_to_resume(tmp_path / "new", resume=False) is None
    with pytest.raises(RankGameError, match="no checkpoint to resume from"):
        checkpoint_to_resume(tmp_path / "new", resume=True)


def test_a_run_with_a_checkpoint_is_resumed_and_never_overwritten(tmp_path: Path) -> None:
    (tmp_path / "metrics.csv").write_text("env_steps\n1000\n")
    (tmp_path / CHECKPOINT_NAME).write_bytes(b"")
    assert checkpoint_to_resume(tmp_path, resume=True) == tmp_path / CHECKPOINT_NAME
    with pytest.raises(RankGameError, match="already holds a run"):
        checkpoint_to_resume(tmp_path, resume=False)


def test_a_run_stopped_before_its_first_checkpoint_starts_again(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "metrics.csv").write_text("env_steps\n1000\n")
    with pytest.raises(RankGameError, match="already holds a run"):
        checkpoint_to_resume(tmp_path, resume=False)
    assert checkpoint_to_resume(tmp_path, resume=True) is None
    assert "starting it again at step 0" in capsys.readouterr().err


def test_a_resumed_run_may_change_only_its_run_control_options() -> None:
    saved = {"steps": 1000, "eval_every": 100, "k": 10.0, "sac": {"hidden_sizes": [256, 256], "gamma": 0.99}}
    longer = {**saved, "steps": 5000, "eval_every": 500}
    require_same_settings(saved, longer, RUN_CONTROL_OPTIONS)  # no error
    with pytest.raises(RankGameError, match=r"^--sac.hidden-sizes 64 64 differs from the checkpoint's 256 256;"):
        require_same_settings(saved, {**saved, "sac": {"hidden_sizes": [64, 64], "gamma": 0.99}}, RUN_CONTROL_OPTIONS)
    with pytest.raises(RankGameError, match=r"^--k 5.0 differs"):
        require_same_settings(saved, {**saved, "k": 5.0}, RUN_CONTROL_OPTIONS)
    with pytest.raises(RankGameError, match=r"^--expert x.npz differs from the checkpoint's \(not given\)"):
        require_same_settings({**saved, "expert": None}, {**saved, "expert": "x.npz"}, RUN_CONTROL_OPTIONS)


def test_an_option_added_after_the_checkpoint_is_accepted_at_its_default() -> None:
    saved = {"steps": 1000, "k": 10.0, "reward": {"lr": 1e-3}}  # written before `termination` and `ral_passes`
    defaults = {"steps": 300_000, "k": 10.0, "termination": "absorbing", "reward": {"lr": 1e-3, "ral_passes": 1.0}}
    same = {**saved, "termination": "absorbing", "reward": {"lr": 1e-3, "ral_passes": 1.0}}
    require_same_settings(saved, same, RUN_CONTROL_OPTIONS, defaults)  # no error
    with pytest.raises(RankGameError, match=r"^--termination done differs from the checkpoint's \(not given\)"):
        require_same_settings(saved, {**same, "termination": "done"}, RUN_CONTROL_OPTIONS, defaults)
    with pytest.raises(RankGameError, match=r"^--reward.ral-passes 6.0 differs"):
        require_same_settings(saved, {**same, "reward": {"lr": 1e-3, "ral_passes": 6.0}}, RUN_CONTROL_OPTIONS, defaults)
    with pytest.raises(RankGameError, match=r"differs from the checkpoint.s \(not given\)"):  # no defaults
        require_same_settings(saved, same, RUN_CONTROL_OPTIONS)


def test_a_checkpoint_of_something_else_is_refused_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / CHECKPOINT_NAME
    save_checkpoint(path, {"note": "not a run"}, {"weights": np.zeros(2)})
    with pytest.raises(RankGameError, match="not a checkpoint of a rankgame run"):
        load_run_checkpoint(path, {}, {}, steps=1000)
