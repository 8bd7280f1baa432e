"""Trajectory files: round trip, validation, and clear errors for bad files."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from rankgame.data.experts import load_shipped_expert, normalized_score, shipped_envs
from rankgame.data.trajectories import Trajectory, load_trajectories, save_trajectories
from rankgame.errors import RankGameError


def _trajectory(length: int, obs_dim: int = 3, act_dim: int = 2, terminated: bool = False) -> Trajectory:
    rng = np.random.default_rng(length)
    term = np.zeros(length, bool)
    trunc = np.zeros(length, bool)
    (term if terminated else trunc)[-1] = True
    return Trajectory(
        obs=rng.normal(size=(length + 1, obs_dim)).astype(np.float32),
        acts=rng.normal(size=(length, act_dim)).astype(np.float32),
        rews=np.ones(length, np.float32),
        terminated=term,
        truncated=trunc,
    )


@pytest.fixture
def saved(tmp_path: Path) -> Path:
    trajs = [_trajectory(5), _trajectory(3, terminated=True)]
    return save_trajectories(tmp_path / "t.npz", "Toy-v0", trajs, seed=3)


def test_round_trip_keeps_episodes_and_metadata(saved: Path) -> None:
    data = load_trajectories(saved, env_id="Toy-v0")
    assert [len(t) for t in data.trajectories] == [5, 3]
    assert data.obs_dim == 3 and data.act_dim == 2
    np.testing.assert_array_equal(data.returns, [5.0, 3.0])
    assert data.metadata["seed"] == 3 and data.metadata["return_mean"] == 4.0
    assert data.trajectories[1].terminated[-1] and not data.trajectories[0].terminated.any()
    np.testing.assert_array_equal(data.trajectories[1].obs, _trajectory(3, terminated=True).obs)


def test_trajectory_validation_messages() -> None:
    good = _trajectory(4)
    with pytest.raises(ValueError, match="T \\+ 1"):
        Trajectory(good.obs[:-1], good.acts, good.rews, good.terminated, good.truncated)
    bad_obs = good.obs.copy()
    bad_obs[1, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Trajectory(bad_obs, good.acts, good.rews, good.terminated, good.truncated)
    early = good.terminated.copy()
    early[0] = True
    with pytest.raises(ValueError, match="only the last step"):
        Trajectory(good.obs, good.acts, good.rews, early, good.truncated)


def test_wrong_env_is_rejected(saved: Path) -> None:
    with pytest.raises(RankGameError, match="recorded on Toy-v0, not Hopper-v5"):
        load_trajectories(saved, env_id="Hopper-v5")


def test_missing_empty_and_truncated_files_are_rejected(saved: Path, tmp_path: Path) -> None:
    with pytest.raises(RankGameError, match="not found"):
        load_trajectories(tmp_path / "nope.npz")
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    with pytest.raises(RankGameError, match="unreadable or truncated"):
        load_trajectories(empty)
    truncated = tmp_path / "cut.npz"
    truncated.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    with pytest.raises(RankGameError, match="unreadable or truncated"):
        load_trajectories(truncated)
    text = tmp_path / "notes.txt"
    text.write_text("obs,acts\n1,2\n")
    with pytest.raises(
        RankGameError, match=r"notes.txt: unreadable or truncated trajectory file \(not an .npz archive\)$"
    ):
        load_trajectories(text)
    with pytest.raises(RankGameError, match="is a folder; pass a rankgame trajectory file"):
        load_trajectories(tmp_path)


def _rewrite(path: Path, out: Path, **changes: np.ndarray) -> Path:
    with np.load(path) as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays.update(changes)
    np.savez(out, **arrays)
    return out


def test_corrupt_contents_are_rejected(saved: Path, tmp_path: Path) -> None:
    with np.load(saved) as archive:
        obs, lengths, meta = archive["obs"].copy(), archive["lengths"], json.loads(str(archive["metadata"]))
    nan_obs = obs.copy()
    nan_obs[2, 0] = np.inf
    with pytest.raises(RankGameError, match="NaN or infinite"):
        load_trajectories(_rewrite(saved, tmp_path / "a.npz", obs=nan_obs))
    with pytest.raises(RankGameError, match="obs has 7 rows; the episode lengths need 10"):
        load_trajectories(_rewrite(saved, tmp_path / "b.npz", obs=obs[:-3]))
    with pytest.raises(RankGameError, match="lengths need"):
        load_trajectories(_rewrite(saved, tmp_path / "c.npz", lengths=lengths + 1))
    meta["obs_dim"] = 99
    with pytest.raises(RankGameError, match="metadata says"):
        load_trajectories(_rewrite(saved, tmp_path / "d.npz", metadata=np.asarray(json.dumps(meta))))
    with pytest.raises(RankGameError, match="version 7"):
        load_trajectories(_rewrite(saved, tmp_path / "e.npz", version=np.asarray(7)))
    np.savez(tmp_path / "f.npz", x=np.zeros(3))
    with pytest.raises(RankGameError, match="not a rankgame trajectory file"):
        load_trajectories(tmp_path / "f.npz")


def test_normalized_score() -> None:
    assert normalized_score(110.0, expert_return=210.0, random_return=10.0) == pytest.approx(50.0)
    assert normalized_score(10.0, 210.0, 10.0) == 0.0
    assert np.isnan(normalized_score(5.0, expert_return=0.0, random_return=0.0))  # undefined, not an exception


#: Mean expert return each shipped file must reach (the foundation issue's targets).
EXPERT_RETURN_TARGETS = {
    "Hopper-v5": 3000,
    "HalfCheetah-v5": 10000,
    "Walker2d-v5": 4000,
    "Ant-v5": 4500,
    "Humanoid-v5": 5000,
}


def test_every_shipped_expert_file_loads_with_its_provenance() -> None:
    envs = shipped_envs()
    assert set(EXPERT_RETURN_TARGETS) | {"Swimmer-v5"} <= set(envs)
    for env_id, target in EXPERT_RETURN_TARGETS.items():
        assert load_shipped_expert(env_id).returns.mean() >= target, env_id
    for env_id in envs:
        data = load_shipped_expert(env_id)
        assert len(data.trajectories) >= 10
        meta = data.metadata
        assert meta["command"].startswith("rankgame ")
        assert np.isfinite(meta["random_return_mean"])
        assert data.returns.mean() > meta["random_return_mean"]
        assert meta["versions"]["gymnasium"] and meta["versions"]["mujoco"]


def test_a_variant_without_contact_forces_ships_its_tasks_expert_data_without_them() -> None:
    from rankgame.envs.variants import ANT_NO_CONTACT_ID

    source, variant = load_shipped_expert("Ant-v5"), load_shipped_expert(ANT_NO_CONTACT_ID)
    assert (variant.env_id, variant.obs_dim, variant.act_dim) == (ANT_NO_CONTACT_ID, 27, 8)
    assert variant.metadata["derived_from"] == "Ant-v5"
    assert variant.metadata["random_return_mean"] == source.metadata["random_return_mean"]
    np.testing.assert_array_equal(variant.returns, source.returns)
    for short, full in zip(variant.trajectories, source.trajectories, strict=True):
        np.testing.assert_array_equal(short.obs, full.obs[:, :27])
        np.testing.assert_array_equal(short.acts, full.acts)
    with pytest.raises(ValueError, match="cannot keep 106 of 105"):
        source.with_leading_obs(106, ANT_NO_CONTACT_ID)


def test_namespaced_ids_name_their_shipped_files_with_a_double_underscore(tmp_path: Path) -> None:
    from rankgame.data import shipped_ids, shipped_path

    for name in ("rankgame__HopperBackward-v5.npz", "Hopper-v5.npz"):
        (tmp_path / name).write_bytes(b"")
    assert shipped_ids(tmp_path) == ["Hopper-v5", "rankgame/HopperBackward-v5"]
    path = shipped_path(tmp_path, "rankgame/HopperBackward-v5", "data", "make some")
    assert path == tmp_path / "rankgame__HopperBackward-v5.npz"
    message = "no shipped data for 'rankgame/Other-v0' (available: Hopper-v5, rankgame/HopperBackward-v5); make some"
    with pytest.raises(RankGameError, match=re.escape(message)):
        shipped_path(tmp_path, "rankgame/Other-v0", "data", "make some")


def test_no_shipped_data_errors_list_every_id_whose_shipped_data_resolves() -> None:
    from rankgame.data import shipped_ids
    from rankgame.data.experts import shipped_expert_path
    from rankgame.data.preferences import PREFERENCE_DIR, shipped_preferences_path
    from rankgame.envs.variants import ANT_NO_CONTACT_ID, HOPPER_HEAVY_ID, HUMANOID_NO_CONTACT_ID

    lookups = {
        "expert data": (shipped_expert_path, shipped_envs()),
        "preference data": (shipped_preferences_path, shipped_ids(PREFERENCE_DIR)),
    }
    assert {ANT_NO_CONTACT_ID, HUMANOID_NO_CONTACT_ID} <= set(shipped_envs())
    for what, (lookup, resolving) in lookups.items():
        for env_id in resolving:
            assert lookup(env_id).is_file(), (what, env_id)
        with pytest.raises(RankGameError) as info:
            lookup(HOPPER_HEAVY_ID)
        listed = re.search(r"\(available: (.*)\);", str(info.value))
        assert listed is not None and listed.group(1).split(", ") == resolving, (what, str(info.value))
