"""Checkpoints and resuming: tree-path keys, finiteness, which checkpoint a run continues from, and which
settings may change."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rankgame.checkpoint import (
    CHECKPOINT_NAME,
    RUN_CONTROL_OPTIONS,
    flatten_tree,
    load_checkpoint,
    require_same_settings,
    save_checkpoint,
    unflatten_tree,
)
from rankgame.errors import NonFiniteError, RankGameError
from rankgame.run import RunSettings, open_run


def _settings(out: Path, resume: bool, steps: int = 1000) -> RunSettings:
    return RunSettings(out, steps, 100, 100, resume, tensorboard=False, progress=False, description="test")


def test_checkpoint_arrays_are_keyed_by_their_tree_path_and_restore_exactly() -> None:
    tree = {"params": {"Dense_0": {"kernel": jnp.ones((2, 3)), "bias": jnp.zeros(3)}}, "key": jax.random.key(7)}
    flat = flatten_tree("reward", tree)
    assert set(flat) == {"reward/params/Dense_0/kernel", "reward/params/Dense_0/bias", "reward/key"}
    template = jax.tree.map(jnp.zeros_like, {"params": tree["params"]}) | {"key": jax.random.key(0)}
    restored = unflatten_tree("reward", flat, template)
    np.testing.assert_array_equal(restored["params"]["Dense_0"]["kernel"], np.ones((2, 3)))
    assert jax.random.key_data(restored["key"]).tolist() == jax.random.key_data(tree["key"]).tolist()
    with pytest.raises(RankGameError, match=r"reward/params/Dense_0/bias is missing"):
        unflatten_tree("reward", {k: v for k, v in flat.items() if not k.endswith("bias")}, template)


def test_a_checkpoint_with_a_non_finite_array_is_never_written(tmp_path: Path) -> None:
    path = tmp_path / CHECKPOINT_NAME
    save_checkpoint(path, {"config": {}, "env_steps": 1}, {"a": np.ones(2)})
    with pytest.raises(NonFiniteError, match=r"^b is not finite$"):
        save_checkpoint(path, {"config": {}, "env_steps": 2}, {"a": np.ones(2), "b": np.array([1.0, np.nan])})
    metadata, arrays = load_checkpoint(path)  # the previous checkpoint is intact
    assert metadata["env_steps"] == 1 and set(arrays) == {"a"}


def test_a_new_folder_starts_at_step_0_and_cannot_be_resumed(tmp_path: Path) -> None:
    assert open_run(_settings(tmp_path / "new", resume=False), {}).metadata is None
    with pytest.raises(RankGameError, match="no checkpoint to resume from"):
        open_run(_settings(tmp_path / "new", resume=True), {})


def test_a_run_with_a_checkpoint_is_resumed_and_never_overwritten(tmp_path: Path) -> None:
    (tmp_path / "metrics.csv").write_text("env_steps\n1000\n")
    save_checkpoint(tmp_path / CHECKPOINT_NAME, {"config": {"k": 1}, "env_steps": 500}, {"a": np.ones(1)})
    assert open_run(_settings(tmp_path, resume=True), {"k": 1}).metadata["env_steps"] == 500
    with pytest.raises(RankGameError, match="already holds a run"):
        open_run(_settings(tmp_path, resume=False), {"k": 1})
    with pytest.raises(RankGameError, match=r"--steps 400 is below the checkpoint's 500 steps"):
        open_run(_settings(tmp_path, resume=True, steps=400), {"k": 1})


def test_a_run_stopped_before_its_first_checkpoint_starts_again(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "metrics.csv").write_text("env_steps\n1000\n")
    with pytest.raises(RankGameError, match="already holds a run"):
        open_run(_settings(tmp_path, resume=False), {})
    assert open_run(_settings(tmp_path, resume=True), {}).metadata is None
    assert "starting it again at step 0" in capsys.readouterr().err


def test_a_resumed_run_may_change_only_its_run_control_options() -> None:
    saved = {"steps": 1000, "eval_every": 100, "rankings": {"k": 10.0}, "sac": {"hidden_sizes": [256, 256]}}
    longer = {**saved, "steps": 5000, "eval_every": 500}
    require_same_settings(saved, longer, RUN_CONTROL_OPTIONS)  # no error
    with pytest.raises(RankGameError, match=r"^--sac.hidden-sizes 64 64 differs from the run's 256 256;"):
        require_same_settings(saved, {**saved, "sac": {"hidden_sizes": [64, 64]}}, RUN_CONTROL_OPTIONS)
    with pytest.raises(RankGameError, match=r"^--rankings.k 5.0 differs"):
        require_same_settings(saved, {**saved, "rankings": {"k": 5.0}}, RUN_CONTROL_OPTIONS)
    with pytest.raises(RankGameError, match=r"^--expert x.npz differs from the run's \(not given\)"):
        require_same_settings({**saved, "expert": None}, {**saved, "expert": "x.npz"}, RUN_CONTROL_OPTIONS)


def test_a_checkpoint_of_something_else_is_refused_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / CHECKPOINT_NAME
    save_checkpoint(path, {"note": "not a run"}, {"weights": np.zeros(2)})
    with pytest.raises(RankGameError, match="not a checkpoint of a rankgame run"):
        load_checkpoint(path)


def test_a_checkpoint_of_an_earlier_layout_is_refused_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / CHECKPOINT_NAME
    payload = {"metadata": np.asarray('{"config": {"k": 10.0}, "env_steps": 1000}'), "sac/0": np.zeros(2)}
    np.savez(path, **payload)  # positional keys and no layout version, as earlier versions wrote
    with pytest.raises(RankGameError, match=r"has checkpoint layout 1; this rankgame reads layout 2: start the run"):
        load_checkpoint(path)
