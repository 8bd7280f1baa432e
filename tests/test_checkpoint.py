"""Which checkpoint a run continues from (``--resume``), for every state its output folder can be in."""

from __future__ import annotations

from pathlib import Path

import pytest

from rankgame.checkpoint import CHECKPOINT_NAME, checkpoint_to_resume
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
