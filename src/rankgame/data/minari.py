"""Minari datasets as a second trajectory format, beside rankgame's own ``.npz`` files.

`Minari <https://minari.farama.org>`_ is the Farama Foundation's format for offline RL datasets. This
module owns the conversion in both directions and the ``minari:DATASET_ID`` reference that names a
Minari dataset wherever a data path is accepted (``--expert minari:pointgoal/expert-v0``). A path
only counts as a reference when its text starts with ``minari:``. To name an ordinary file called
``minari:x.npz``, give it a folder (``data/minari:x.npz``) or an absolute path: ``Path`` drops a leading ``./``.

Only *local* datasets are used, found in Minari's datasets root: ``$MINARI_DATASETS_PATH`` when that is
set (read at each call), ``~/.minari/datasets`` otherwise. Nothing is ever downloaded; fetch a remote
dataset first with ``minari download DATASET_ID``. Dataset ids have Minari's form
``(namespace/)name-vN``.

One Minari episode is one :class:`~rankgame.data.trajectories.Trajectory`: observations
``(T + 1, obs_dim)``, actions ``(T, act_dim)`` in environment units, rewards, terminations and
truncations ``(T,)``. Only flat ``Box`` observation and action spaces are supported. A dataset written
here records:

* the environment: Minari's ``env_spec`` (from the Gymnasium registry, without making the environment;
  a spec whose entry point is a class is stored with the class's import path) and, always, the
  ``env_id`` in the ``rankgame`` metadata entry, which :func:`read_minari` prefers;
* every entry of the trajectory file's metadata under the dataset metadata key ``rankgame`` (the random
  policy's return ``random_return_mean``, ``ranks`` of people's rankings, the command, seeds, ...);
* Minari's own ``ref_min_score`` (the random return) and ``ref_max_score`` (the data's mean return) when
  the data has a finite ``random_return_mean``, so that ``minari.get_normalized_score`` works.

The spaces stored are ``Box(-inf, inf, (obs_dim,))`` and ``Box(-inf, inf, (act_dim,))`` in float32: the
trajectory file does not carry the action bounds; recover the environment for them. A dataset made by
other tools has no ``rankgame`` entry: its environment comes from its ``env_spec``, its random return
from its ``ref_min_score`` if any, and a ranking of its episodes from their returns.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import uuid
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np

from rankgame.data.trajectories import Trajectory, TrajectoryFile, derived_metadata, load_trajectories
from rankgame.errors import RankGameError

#: A data path that starts with this names a local Minari dataset: ``minari:DATASET_ID``.
MINARI_PREFIX = "minari:"
#: The dataset metadata entry that keeps the trajectory file's metadata.
RANKGAME_METADATA_KEY = "rankgame"
MISSING_EXTRA = "Minari support needs the minari extra: pip install 'rankgame[minari]'"


def is_minari_ref(path: str | os.PathLike[str] | None) -> bool:
    """Whether a data path names a Minari dataset (``minari:DATASET_ID``); ``Path("minari:x")`` counts."""
    return path is not None and str(path).startswith(MINARI_PREFIX)


def minari_dataset_id(ref: str | os.PathLike[str]) -> str:
    """The dataset id of a ``minari:DATASET_ID`` reference; a :class:`RankGameError` if it names none."""
    text = str(ref)
    if not text.startswith(MINARI_PREFIX) or not text[len(MINARI_PREFIX) :]:
        raise RankGameError(f"{text!r} is not a Minari reference: use {MINARI_PREFIX}DATASET_ID")
    return text[len(MINARI_PREFIX) :]


def write_minari(data: TrajectoryFile, dataset_id: str, *, overwrite: bool = False) -> Path:
    """Write a trajectory file's episodes as the local Minari dataset ``dataset_id``.

    Each trajectory becomes one episode: observations ``(T + 1, obs_dim)``, actions ``(T, act_dim)``,
    rewards, terminations and truncations ``(T,)``, stored in float32 / bool in Minari's HDF5 format.
    The dataset is built in a hidden folder beside its destination and moved into place when complete,
    so a failed write leaves no partial dataset under ``dataset_id``.

    Args:
        data: the trajectories and their metadata (kept under the dataset metadata key ``rankgame``).
        dataset_id: Minari id ``(namespace/)name-vN``.
        overwrite: replace an existing local dataset with this id instead of refusing.
    Returns:
        The dataset's folder, ``<datasets root>/<dataset_id>``.
    Raises:
        RankGameError: with a one-line reason (malformed or taken id, no episodes, mixed dimensions,
            Minari not installed).
    """
    minari = _import_minari()
    from minari.data_collector.episode_buffer import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage
    from minari.namespace import create_namespace, list_local_namespaces
    from minari.storage.datasets_root_dir import get_dataset_path

    namespace = _parse_dataset_id(dataset_id)
    if not data.trajectories:
        raise RankGameError(f"no trajectories to write to Minari dataset {dataset_id!r}")
    obs_dim, act_dim = data.obs_dim, data.act_dim
    for i, traj in enumerate(data.trajectories):
        if traj.obs.shape[1] != obs_dim or traj.acts.shape[1] != act_dim:
            raise RankGameError(
                f"trajectory {i} has obs_dim={traj.obs.shape[1]}, act_dim={traj.acts.shape[1]}; "
                f"the first has obs_dim={obs_dim}, act_dim={act_dim}"
            )
    final = Path(get_dataset_path(dataset_id))
    if final.exists():
        if not overwrite:
            raise RankGameError(
                f"Minari dataset {dataset_id!r} already exists at {final}; pass --overwrite to replace it"
            )
        if not (final / "data").is_dir():
            raise RankGameError(f"{final} exists but is not a Minari dataset; refusing to replace it")
    if namespace is not None and namespace not in list_local_namespaces():
        create_namespace(namespace)
    final.parent.mkdir(parents=True, exist_ok=True)

    staging = final.parent / f".{final.name}.rankgame-{uuid.uuid4().hex[:12]}"
    try:
        staging.mkdir()
        storage = MinariStorage.new(
            staging / "data",
            observation_space=gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32),
            action_space=gym.spaces.Box(-np.inf, np.inf, (act_dim,), np.float32),
            env_spec=_serializable_spec(data.env_id),
            data_format="hdf5",
            jpeg_encoding=False,
        )
        storage.update_metadata(_dataset_metadata(data, dataset_id, minari.__version__))
        storage.update_episodes(
            [
                EpisodeBuffer(
                    observations=np.asarray(traj.obs, np.float32),
                    actions=np.asarray(traj.acts, np.float32),
                    rewards=np.asarray(traj.rews, np.float32),
                    terminations=np.asarray(traj.terminated, bool),
                    truncations=np.asarray(traj.truncated, bool),
                )
                for traj in data.trajectories
            ]
        )
        _move_into_place(staging, final)
    except ImportError:
        raise RankGameError(MISSING_EXTRA) from None
    except (OSError, ValueError, TypeError) as exc:
        raise RankGameError(f"could not write Minari dataset {dataset_id!r}: {_one_line(exc)}") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return final


def read_minari(dataset_id: str, env_id: str | None = None) -> TrajectoryFile:
    """Load the local Minari dataset ``dataset_id`` as a validated trajectory file.

    Episodes are read as observations ``(T + 1, obs_dim)``, actions ``(T, act_dim)`` and rewards
    ``(T,)`` in float32, terminations and truncations ``(T,)`` bool, and validated as a native file's
    are (sizes, flags only at the last step, no NaN or infinity). The metadata is the one kept under
    ``rankgame`` by :func:`write_minari` (if any), with the counts, dimensions and returns recomputed
    from the episodes and ``minari_dataset_id`` added.

    Args:
        dataset_id: Minari id ``(namespace/)name-vN`` of a dataset in the local datasets root.
        env_id: if given, the dataset must have been recorded on this environment.
    Raises:
        RankGameError: with a one-line reason for a missing, unreadable, non-flat, mismatched or
            invalid dataset, or for Minari not being installed. Nothing is downloaded.
    """
    minari = _import_minari()
    from minari.storage.datasets_root_dir import get_dataset_path

    ref = f"{MINARI_PREFIX}{dataset_id}"
    _parse_dataset_id(dataset_id)
    if not (Path(get_dataset_path(dataset_id)) / "data").is_dir():
        raise RankGameError(
            f"no local Minari dataset {dataset_id!r} in {get_dataset_path()}: {MINARI_PREFIX}ID must name a local "
            f"dataset (nothing is downloaded; fetch a remote one first with `minari download {dataset_id}`)"
        )
    try:
        dataset = minari.load_dataset(dataset_id, download=False)
        raw = dataset.storage.metadata
        obs_space, act_space = dataset.observation_space, dataset.action_space
        spec = dataset.env_spec
    except ImportError as exc:  # an Arrow or Parquet dataset needs pyarrow, which the extra does not bring
        raise RankGameError(f"{ref}: {_one_line(exc)}" if "pyarrow" in str(exc) else MISSING_EXTRA) from None
    except (OSError, ValueError, KeyError, TypeError, AssertionError, json.JSONDecodeError) as exc:
        raise RankGameError(f"{ref}: unreadable Minari dataset ({_one_line(exc)})") from None
    for what, space in (("observation", obs_space), ("action", act_space)):
        if not isinstance(space, gym.spaces.Box) or len(space.shape) != 1:
            raise RankGameError(f"{ref}: rankgame needs flat Box observations and actions, not a {what} space {space}")
    stored = raw.get(RANKGAME_METADATA_KEY)
    stored = dict(stored) if isinstance(stored, dict) else {}
    file_env = stored.get("env_id", spec.id if spec is not None else None)
    if not isinstance(file_env, str):
        raise RankGameError(f"{ref}: the dataset records no environment (it has no env_spec)")
    if env_id is not None and file_env != env_id:
        raise RankGameError(f"{ref}: trajectories were recorded on {file_env}, not {env_id}")
    if dataset.total_episodes == 0:
        raise RankGameError(f"{ref}: the dataset holds no episodes")
    dims = (int(obs_space.shape[0]), int(act_space.shape[0]))
    try:
        trajectories = tuple(
            _episode_trajectory(episode, dims, index) for index, episode in enumerate(dataset.iterate_episodes())
        )
    except ImportError:
        raise RankGameError(MISSING_EXTRA) from None
    except (ValueError, OSError, KeyError, TypeError) as exc:
        raise RankGameError(f"{ref}: {_one_line(exc)}") from None
    if "random_return_mean" not in stored and isinstance(raw.get("ref_min_score"), int | float):
        stored["random_return_mean"] = float(raw["ref_min_score"])
    metadata = {**stored, **derived_metadata(file_env, trajectories), "minari_dataset_id": dataset_id}
    return TrajectoryFile(env_id=file_env, trajectories=trajectories, metadata=metadata)


def to_minari(file: Path, dataset_id: str, overwrite: bool = False) -> dict[str, Any]:
    """Convert the native trajectory file ``file`` into the local Minari dataset ``dataset_id``.

    Returns:
        A summary: ``dataset_id``, ``ref`` (the ``minari:`` reference to pass as a data path),
        ``env_id``, ``episodes``, ``steps`` and ``path`` (the dataset's folder).
    """
    data = load_trajectories(file)
    path = write_minari(data, dataset_id, overwrite=overwrite)
    return {
        "dataset_id": dataset_id,
        "ref": f"{MINARI_PREFIX}{dataset_id}",
        "env_id": data.env_id,
        "episodes": len(data.trajectories),
        "steps": int(sum(len(t) for t in data.trajectories)),
        "path": str(path),
    }


def _import_minari() -> ModuleType:
    """The ``minari`` package with its HDF5 storage, or the one-line error naming the extra."""
    try:
        import h5py  # noqa: F401  (Minari's default storage)
        import minari
    except ImportError:
        raise RankGameError(MISSING_EXTRA) from None
    return minari


def _parse_dataset_id(dataset_id: str) -> str | None:
    """The namespace of a well-formed Minari id ``(namespace/)name-vN`` (None without one)."""
    from minari.dataset.minari_dataset import parse_dataset_id

    try:
        namespace, _, _ = parse_dataset_id(dataset_id)
    except (ValueError, TypeError):
        raise RankGameError(
            f"malformed Minari dataset id {dataset_id!r}: use (namespace/)name-vN, e.g. pointgoal/expert-v0"
        ) from None
    return namespace


def _serializable_spec(env_id: str) -> gym.envs.registration.EnvSpec | None:
    """The registered Gymnasium spec of ``env_id`` in a form Minari can store as JSON, or None.

    A class or function entry point is replaced by its import path ``module:name``; a spec that still
    does not serialize (or an unregistered id) gives None, and the id is kept in the metadata only.
    """
    import rankgame.envs  # noqa: F401  (registers rankgame's own tasks)

    try:
        spec = gym.spec(env_id)
    except gym.error.Error:
        return None
    if callable(spec.entry_point):
        entry: Callable[..., Any] = spec.entry_point
        spec = dataclasses.replace(spec, entry_point=f"{entry.__module__}:{entry.__qualname__}")
    try:
        spec.to_json()
    except (ValueError, TypeError):
        return None
    return spec


def _dataset_metadata(data: TrajectoryFile, dataset_id: str, minari_version: str) -> dict[str, Any]:
    """Minari dataset metadata: id, version, a description, reference scores and the ``rankgame`` entry."""
    source = data.metadata.get("source")
    metadata: dict[str, Any] = {
        "dataset_id": dataset_id,
        "minari_version": minari_version,
        "description": f"{len(data.trajectories)} episodes of {data.env_id}, written by rankgame",
        RANKGAME_METADATA_KEY: {**data.metadata, "env_id": data.env_id},
    }
    if isinstance(source, str):
        metadata["algorithm_name"] = source
    random_return = data.metadata.get("random_return_mean")
    if isinstance(random_return, int | float) and math.isfinite(random_return):
        metadata["ref_min_score"] = float(random_return)
        metadata["ref_max_score"] = float(np.mean(data.returns))
        if isinstance(data.metadata.get("random_episodes"), int):
            metadata["num_episodes_average_score"] = data.metadata["random_episodes"]
    return metadata


def _episode_trajectory(episode: Any, dims: tuple[int, int], index: int) -> Trajectory:
    """One Minari episode as a validated :class:`Trajectory` of ``dims = (obs_dim, act_dim)``."""
    obs = np.asarray(episode.observations, np.float32)
    acts = np.asarray(episode.actions, np.float32)
    for name, array, dim in (("observations", obs, dims[0]), ("actions", acts, dims[1])):
        if array.ndim != 2 or array.shape[1] != dim:
            raise ValueError(f"episode {index}: {name} have shape {array.shape}; the dataset's space needs (_, {dim})")
    try:
        return Trajectory(
            obs=obs,
            acts=acts,
            rews=np.asarray(episode.rewards, np.float32),
            terminated=np.asarray(episode.terminations, bool),
            truncated=np.asarray(episode.truncations, bool),
        )
    except ValueError as exc:
        raise ValueError(f"episode {index}: {exc}") from None


def _move_into_place(staging: Path, final: Path) -> None:
    """Rename the complete dataset folder ``staging`` to ``final``, replacing an existing dataset there."""
    if not final.exists():
        os.replace(staging, final)
        return
    retired = final.parent / f".{final.name}.rankgame-old-{uuid.uuid4().hex[:12]}"
    os.replace(final, retired)
    try:
        os.replace(staging, final)
    except OSError:
        os.replace(retired, final)
        raise
    shutil.rmtree(retired, ignore_errors=True)


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__
