"""Minari datasets: native <-> Minari round trip, ``minari:ID`` data paths, and one-line errors."""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import minari
import numpy as np
import pytest
from minari.data_collector.episode_buffer import EpisodeBuffer

from rankgame.data.experts import load_expert_data
from rankgame.data.minari import (
    MINARI_PREFIX,
    MISSING_EXTRA,
    is_minari_ref,
    minari_dataset_id,
    read_minari,
    to_minari,
    write_minari,
)
from rankgame.data.preferences import load_preferences
from rankgame.data.trajectories import TrajectoryFile, load_trajectories, save_trajectories
from rankgame.envs.toy import POINT_GOAL_ID, POINT_GOAL_MIRRORED_ID
from rankgame.errors import RankGameError

DATASET_ID = "pointgoal/expert-v0"
FIELDS = ("obs", "acts", "rews", "terminated", "truncated")


@pytest.fixture
def minari_root(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty local Minari datasets root, named by ``MINARI_DATASETS_PATH`` only after minari was imported."""
    assert "minari" in sys.modules  # so the tests below show the root is read at call time
    root = tmp_path / "minari-datasets"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return root


def _assert_same_episodes(got: TrajectoryFile, want: TrajectoryFile) -> None:
    assert got.env_id == want.env_id
    assert len(got.trajectories) == len(want.trajectories)
    for a, b in zip(got.trajectories, want.trajectories, strict=True):
        for name in FIELDS:
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and x.shape == y.shape, name
            np.testing.assert_array_equal(x, y, err_msg=name)


def _one_line_error(excinfo: pytest.ExceptionInfo[RankGameError], *fragments: str) -> str:
    message = str(excinfo.value)
    assert "\n" not in message and message, message
    for fragment in fragments:
        assert fragment in message, message
    return message


def _foreign_dataset(dataset_id: str, episodes: list[EpisodeBuffer], **kwargs: Any) -> None:
    """Write a dataset with Minari's own API, as another tool would (Minari warns about missing authors)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        minari.create_dataset_from_buffers(dataset_id, episodes, **kwargs)


def _pendulum_episode(length: int, nan_at: int | None = None) -> EpisodeBuffer:
    obs = np.linspace(-1.0, 1.0, (length + 1) * 3, dtype=np.float32).reshape(length + 1, 3)
    if nan_at is not None:
        obs[nan_at, 1] = np.nan
    truncations = np.zeros(length, bool)
    truncations[-1] = True
    return EpisodeBuffer(
        observations=obs,
        actions=np.full((length, 1), 0.5, np.float32),
        rewards=-np.arange(length, dtype=np.float32),
        terminations=np.zeros(length, bool),
        truncations=truncations,
    )


def test_native_to_minari_to_native_keeps_arrays_env_and_metadata(minari_root: Path, toy_expert_file: Path) -> None:
    native = load_trajectories(toy_expert_file)
    summary = to_minari(toy_expert_file, DATASET_ID)
    assert summary == {
        "dataset_id": DATASET_ID,
        "ref": "minari:pointgoal/expert-v0",
        "env_id": POINT_GOAL_ID,
        "episodes": 10,
        "steps": 400,
        "path": str(minari_root / "pointgoal" / "expert-v0"),
    }
    json.dumps(summary)
    assert (minari_root / "pointgoal" / "expert-v0" / "data" / "metadata.json").is_file()

    back = read_minari(DATASET_ID, POINT_GOAL_ID)
    _assert_same_episodes(back, native)
    np.testing.assert_array_equal(back.returns, native.returns)
    assert back.metadata["random_return_mean"] == native.metadata["random_return_mean"]
    assert back.metadata["lengths"] == native.metadata["lengths"] == [40] * 10
    assert back.metadata["obs_dim"] == 2 and back.metadata["act_dim"] == 1
    assert back.metadata["minari_dataset_id"] == DATASET_ID
    assert read_minari(DATASET_ID).env_id == POINT_GOAL_ID  # no env id to check against

    # Minari itself sees a standard dataset: episodes, env spec and reference scores.
    dataset = minari.load_dataset(DATASET_ID)
    assert dataset.total_episodes == 10 and dataset.total_steps == 400
    assert dataset.env_spec is not None and dataset.env_spec.id == POINT_GOAL_ID
    assert dataset.env_spec.max_episode_steps == 40
    episode = dataset[3]
    assert episode.observations.shape == (41, 2) and episode.actions.shape == (40, 1)
    np.testing.assert_array_equal(episode.observations, native.trajectories[3].obs)
    scores = minari.get_normalized_score(
        dataset, np.array([native.metadata["random_return_mean"], native.returns.mean()])
    )
    np.testing.assert_allclose(scores, [0.0, 1.0])
    assert DATASET_ID in minari.list_local_datasets()


def test_datasets_root_is_read_at_call_time(
    minari_root: Path, toy_expert_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    written = write_minari(load_trajectories(toy_expert_file), "toy-v0")
    assert written == minari_root / "toy-v0" and (written / "data").is_dir()
    other = tmp_path / "other-root"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(other))
    with pytest.raises(RankGameError) as excinfo:
        read_minari("toy-v0")
    _one_line_error(excinfo, "'toy-v0'", str(other), "local")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(minari_root))
    assert len(read_minari("toy-v0").trajectories) == 10


def test_expert_and_preference_loaders_accept_minari_refs(
    minari_root: Path, toy_expert_file: Path, toy_preference_file: Path
) -> None:
    native = load_trajectories(toy_expert_file)
    write_minari(native, DATASET_ID)
    assert is_minari_ref(Path("minari:pointgoal/expert-v0")) and str(Path("minari:pointgoal/expert-v0")).startswith(
        MINARI_PREFIX
    )
    # Path drops a leading "./", so a file named like a reference is passed with a folder or absolute path.
    assert str(Path("./minari:expert.npz")) == "minari:expert.npz"
    assert not is_minari_ref("./minari:expert.npz") and not is_minari_ref(Path("data/minari:expert.npz"))
    assert not is_minari_ref(None)
    assert minari_dataset_id(Path("minari:pointgoal/expert-v0")) == DATASET_ID
    for ref in (Path(f"minari:{DATASET_ID}"), f"minari:{DATASET_ID}"):
        _assert_same_episodes(load_expert_data(ref, POINT_GOAL_ID), native)
    _assert_same_episodes(load_expert_data(toy_expert_file, POINT_GOAL_ID), native)

    prefs = load_trajectories(toy_preference_file)
    write_minari(prefs, "pointgoal/prefs-v0")
    data, order = load_preferences(Path("minari:pointgoal/prefs-v0"), POINT_GOAL_ID)
    _assert_same_episodes(data, prefs)
    np.testing.assert_array_equal(order, np.argsort(prefs.returns, kind="stable"))
    assert np.all(np.diff(data.returns[order]) >= 0)

    # Ranks given by people travel in the dataset's rankgame metadata and decide the order.
    ranked = TrajectoryFile(prefs.env_id, prefs.trajectories, {**prefs.metadata, "ranks": [3, 0, 2, 1]})
    write_minari(ranked, "pointgoal/ranked-v0")
    _, order = load_preferences(Path("minari:pointgoal/ranked-v0"), POINT_GOAL_ID)
    np.testing.assert_array_equal(order, [1, 3, 2, 0])


def test_existing_dataset_is_refused_unless_overwrite(minari_root: Path, toy_expert_file: Path) -> None:
    native = load_trajectories(toy_expert_file)
    write_minari(native, DATASET_ID)
    fewer = TrajectoryFile(native.env_id, native.trajectories[:2], native.metadata)
    with pytest.raises(RankGameError) as excinfo:
        write_minari(fewer, DATASET_ID)
    _one_line_error(excinfo, "'pointgoal/expert-v0'", "already exists", "--overwrite")
    assert len(read_minari(DATASET_ID).trajectories) == 10  # left as it was
    write_minari(fewer, DATASET_ID, overwrite=True)
    _assert_same_episodes(read_minari(DATASET_ID), fewer)
    assert minari.load_dataset(DATASET_ID).total_episodes == 2
    assert sorted(p.name for p in (minari_root / "pointgoal").iterdir()) == ["expert-v0", "namespace_metadata.json"]


def test_wrong_env_unknown_and_malformed_ids_give_one_line_errors(
    minari_root: Path, toy_expert_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write_minari(load_trajectories(toy_expert_file), DATASET_ID)
    with pytest.raises(RankGameError) as excinfo:
        load_expert_data(Path(f"minari:{DATASET_ID}"), POINT_GOAL_MIRRORED_ID)
    _one_line_error(excinfo, f"recorded on {POINT_GOAL_ID}, not {POINT_GOAL_MIRRORED_ID}")

    def no_download(*args: object, **kwargs: object) -> None:
        raise AssertionError("a download was attempted")

    monkeypatch.setattr(minari.storage.hosting, "download_dataset", no_download)
    monkeypatch.setattr(minari, "download_dataset", no_download)
    with pytest.raises(RankGameError) as excinfo:
        load_expert_data(Path("minari:mujoco/hopper/expert-v0"), "Hopper-v5")
    _one_line_error(excinfo, "'mujoco/hopper/expert-v0'", "local dataset")
    assert not (minari_root / "mujoco").exists()

    for bad in ("no-version", "../escape-v0"):
        with pytest.raises(RankGameError) as excinfo:
            read_minari(bad)
        _one_line_error(excinfo, repr(bad), "name-vN")
    with pytest.raises(RankGameError) as excinfo:
        minari_dataset_id("minari:")
    _one_line_error(excinfo, "DATASET_ID")


def test_invalid_foreign_datasets_give_one_line_errors(minari_root: Path) -> None:
    box1, box3 = (gym.spaces.Box(-np.inf, np.inf, (n,), np.float32) for n in (1, 3))
    # A valid dataset made by Minari alone: the env id comes from its env_spec, the random return from ref_min_score.
    _foreign_dataset(
        "pendulum/ok-v0", [_pendulum_episode(5)], env="Pendulum-v1", ref_min_score=-1200.0, ref_max_score=0.0
    )
    data = read_minari("pendulum/ok-v0", "Pendulum-v1")
    assert data.env_id == "Pendulum-v1" and data.metadata["random_return_mean"] == -1200.0
    np.testing.assert_array_equal(data.trajectories[0].rews, -np.arange(5, dtype=np.float32))
    assert data.trajectories[0].obs.shape == (6, 3) and data.trajectories[0].truncated[-1]

    _foreign_dataset("pendulum/nan-v0", [_pendulum_episode(5), _pendulum_episode(4, nan_at=2)], env="Pendulum-v1")
    with pytest.raises(RankGameError) as excinfo:
        read_minari("pendulum/nan-v0", "Pendulum-v1")
    _one_line_error(excinfo, "minari:pendulum/nan-v0", "episode 1", "obs contains NaN")

    early = _pendulum_episode(5)
    early.terminations[1] = True
    _foreign_dataset("pendulum/early-v0", [early], env="Pendulum-v1")
    with pytest.raises(RankGameError) as excinfo:
        read_minari("pendulum/early-v0")
    _one_line_error(excinfo, "episode 0", "only the last step")

    discrete = EpisodeBuffer(
        observations=np.zeros((4, 3), np.float32),
        actions=np.zeros(3, np.int64),
        rewards=np.zeros(3, np.float32),
        terminations=np.array([False, False, True]),
        truncations=np.zeros(3, bool),
    )
    _foreign_dataset("discrete-v0", [discrete], observation_space=box3, action_space=gym.spaces.Discrete(2))
    with pytest.raises(RankGameError) as excinfo:
        read_minari("discrete-v0")
    _one_line_error(excinfo, "flat Box", "action space")

    _foreign_dataset("no-env-v0", [_pendulum_episode(3)], observation_space=box3, action_space=box1)
    with pytest.raises(RankGameError) as excinfo:
        read_minari("no-env-v0", "Pendulum-v1")
    _one_line_error(excinfo, "records no environment")


def test_missing_minari_names_the_extra(monkeypatch: pytest.MonkeyPatch, toy_expert_file: Path) -> None:
    monkeypatch.setitem(sys.modules, "minari", None)  # makes `import minari` fail
    for call in (lambda: read_minari(DATASET_ID), lambda: write_minari(load_trajectories(toy_expert_file), DATASET_ID)):
        with pytest.raises(RankGameError) as excinfo:
            call()
        assert _one_line_error(excinfo) == MISSING_EXTRA
    assert MISSING_EXTRA == "Minari support needs the minari extra: pip install 'rankgame[minari]'"
    # An ordinary file is still read without Minari.
    assert len(load_expert_data(toy_expert_file, POINT_GOAL_ID).trajectories) == 10


def test_unwritable_data_gives_one_line_errors_and_no_dataset(minari_root: Path, toy_expert_file: Path) -> None:
    native = load_trajectories(toy_expert_file)
    with pytest.raises(RankGameError) as excinfo:
        write_minari(native, "pointgoal/expert")
    _one_line_error(excinfo, "malformed Minari dataset id")
    first, second = native.trajectories[:2]
    mixed = TrajectoryFile(
        native.env_id, (first, type(second)(second.obs[:, :1], *(getattr(second, f) for f in FIELDS[1:])))
    )
    with pytest.raises(RankGameError) as excinfo:
        write_minari(mixed, "mixed-v0")
    _one_line_error(excinfo, "trajectory 1 has obs_dim=1")
    # An env id Gymnasium does not know is kept in the rankgame metadata alone.
    path = save_trajectories(minari_root.parent / "custom.npz", "my/Custom-v3", list(native.trajectories[:1]), seed=7)
    to_minari(path, "custom-v0")
    assert minari.load_dataset("custom-v0").env_spec is None
    back = read_minari("custom-v0", "my/Custom-v3")
    assert back.env_id == "my/Custom-v3" and back.metadata["seed"] == 7
    assert not (minari_root / "mixed-v0").exists() and not any(p.name.startswith(".") for p in minari_root.iterdir())


def test_the_command_line_round_trip_trains_on_a_minari_dataset(minari_root: Path, toy_expert_file: Path) -> None:
    from conftest import TOY_TRAIN_ARGS, assert_one_line_error, run_cli

    written = run_cli("data", "to-minari", str(toy_expert_file), "pointgoal/expert-v0")
    assert written.returncode == 0, written.stderr
    assert json.loads(written.stdout)["episodes"] == 10
    assert_one_line_error(run_cli("data", "to-minari", str(toy_expert_file), "pointgoal/expert-v0"), "--overwrite")
    out = minari_root.parent / "run"
    args = [*TOY_TRAIN_ARGS, "--expert", "minari:pointgoal/expert-v0", "--steps", "400", "--eval-every", "400"]
    trained = run_cli("train", *args, "--eval-episodes", "1", "--out", str(out))
    assert trained.returncode == 0, trained.stderr
    native = run_cli(
        "train",
        *TOY_TRAIN_ARGS,
        "--expert",
        str(toy_expert_file),
        "--steps",
        "400",
        "--eval-every",
        "400",
        "--eval-episodes",
        "1",
        "--out",
        str(minari_root.parent / "native"),
    )
    # The same data through either format: the same run, number for number.
    assert json.loads(trained.stdout)["eval_return"] == json.loads(native.stdout)["eval_return"]
