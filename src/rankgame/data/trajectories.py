"""Trajectories and the versioned trajectory file format (``.npz``), with strict validation.

File format, version 1 (see ``docs/data.md``): one NumPy ``.npz`` archive holding the
episodes concatenated along time, and where each episode starts:

=================  ===========================  ==============================================
key                shape / dtype                meaning
=================  ===========================  ==============================================
``format``         () str                       ``"rankgame-trajectories"``
``version``        () int64                     ``1``
``metadata``       () str                       JSON: env_id, obs_dim, act_dim, seed, returns, ...
``obs``            (sum(T_i + 1), obs_dim) f32  observations, each episode's final one included
``acts``           (sum(T_i), act_dim) f32      actions, in the environment's own units
``rews``           (sum(T_i),) f32              environment rewards
``terminated``     (sum(T_i),) bool             true terminal state reached after this step
``truncated``      (sum(T_i),) bool             episode cut by a time limit after this step
``lengths``        (n_episodes,) int64          T_i, steps of each episode
=================  ===========================  ==============================================
"""

from __future__ import annotations

import dataclasses
import json
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rankgame.atomic import atomic_write
from rankgame.errors import RankGameError

FORMAT_NAME = "rankgame-trajectories"
FORMAT_VERSION = 1
ARRAY_KEYS = ("obs", "acts", "rews", "terminated", "truncated", "lengths")


@dataclass(frozen=True)
class Trajectory:
    """One episode.

    Attributes:
        obs: ``(T + 1, obs_dim)`` observations ``s_0 .. s_T``.
        acts: ``(T, act_dim)`` actions in environment units.
        rews: ``(T,)`` environment rewards.
        terminated: ``(T,)`` true where the step reached a terminal state (only the last can be).
        truncated: ``(T,)`` true where a time limit cut the episode (only the last can be).
    """

    obs: np.ndarray
    acts: np.ndarray
    rews: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray

    def __post_init__(self) -> None:
        length = len(self.acts)
        if length == 0:
            raise ValueError("a trajectory needs at least one step")
        if self.obs.ndim != 2 or self.acts.ndim != 2:
            raise ValueError(f"obs and acts must be 2-D, got shapes {self.obs.shape} and {self.acts.shape}")
        if self.obs.shape[0] != length + 1:
            raise ValueError(f"obs has {self.obs.shape[0]} rows; expected T + 1 = {length + 1}")
        for name in ("rews", "terminated", "truncated"):
            if getattr(self, name).shape != (length,):
                raise ValueError(f"{name} has shape {getattr(self, name).shape}; expected ({length},)")
        if self.terminated[:-1].any() or self.truncated[:-1].any():
            raise ValueError("only the last step of a trajectory may be terminal or truncated")
        for name in ("obs", "acts", "rews"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"{name} contains NaN or infinite values")

    def __len__(self) -> int:
        return len(self.acts)

    @property
    def ret(self) -> float:
        """Undiscounted return (sum of rewards)."""
        return float(np.sum(self.rews, dtype=np.float64))


@dataclass(frozen=True)
class TrajectoryFile:
    """Trajectories of one environment plus the metadata that says where they came from."""

    env_id: str
    trajectories: tuple[Trajectory, ...]
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def obs_dim(self) -> int:
        return int(self.trajectories[0].obs.shape[1])

    @property
    def act_dim(self) -> int:
        return int(self.trajectories[0].acts.shape[1])

    @property
    def returns(self) -> np.ndarray:
        """``(n_episodes,)`` undiscounted returns."""
        return np.array([traj.ret for traj in self.trajectories])

    def with_leading_obs(self, n_obs: int, env_id: str) -> TrajectoryFile:
        """The same episodes as data of ``env_id``, a task that observes only the first ``n_obs`` entries:
        observations ``(T + 1, obs_dim) -> (T + 1, n_obs)``; actions and rewards unchanged."""
        if not 0 < n_obs <= self.obs_dim:
            raise ValueError(f"cannot keep {n_obs} of {self.obs_dim} observation entries")
        trajectories = tuple(dataclasses.replace(t, obs=t.obs[:, :n_obs]) for t in self.trajectories)
        metadata = {**self.metadata, "env_id": env_id, "obs_dim": n_obs, "derived_from": self.env_id}
        return TrajectoryFile(env_id, trajectories, metadata)


def derived_metadata(env_id: str, trajectories: Sequence[Trajectory]) -> dict[str, Any]:
    """The metadata a trajectory file computes from its episodes: env id, dimensions, counts, returns."""
    returns = [traj.ret for traj in trajectories]
    return {
        "env_id": env_id,
        "obs_dim": int(trajectories[0].obs.shape[1]),
        "act_dim": int(trajectories[0].acts.shape[1]),
        "n_episodes": len(trajectories),
        "returns": returns,
        "return_mean": float(np.mean(returns)),
        "return_std": float(np.std(returns)),
        "lengths": [len(traj) for traj in trajectories],
    }


def save_trajectories(path: str | Path, env_id: str, trajectories: Sequence[Trajectory], **metadata: Any) -> Path:
    """Write trajectories to ``path`` atomically (a crash never leaves a half-written file).

    The metadata is merged with env_id, dimensions, counts and return statistics.
    """
    if not trajectories:
        raise ValueError("no trajectories to save")
    path = Path(path)
    meta = {**metadata, **derived_metadata(env_id, trajectories)}
    arrays = {
        "format": np.asarray(FORMAT_NAME),
        "version": np.asarray(FORMAT_VERSION, np.int64),
        "metadata": np.asarray(json.dumps(meta, sort_keys=True)),
        "obs": np.concatenate([t.obs for t in trajectories]).astype(np.float32),
        "acts": np.concatenate([t.acts for t in trajectories]).astype(np.float32),
        "rews": np.concatenate([t.rews for t in trajectories]).astype(np.float32),
        "terminated": np.concatenate([t.terminated for t in trajectories]).astype(bool),
        "truncated": np.concatenate([t.truncated for t in trajectories]).astype(bool),
        "lengths": np.array([len(t) for t in trajectories], np.int64),
    }
    atomic_write(path, lambda handle: np.savez_compressed(handle, **arrays))
    return path


def load_trajectories(path: str | Path, env_id: str | None = None) -> TrajectoryFile:
    """Read and validate a trajectory file.

    Args:
        path: the ``.npz`` file.
        env_id: if given, the file must have been recorded on this environment.
    Raises:
        RankGameError: with a one-line reason for a missing, truncated, malformed or mismatched file.
    """
    path = Path(path)
    if path.is_dir():
        raise RankGameError(f"{path} is a folder; pass a rankgame trajectory file (.npz)")
    if not path.is_file():
        raise RankGameError(f"trajectory file not found: {path}")
    if not zipfile.is_zipfile(path):
        raise RankGameError(f"{path}: unreadable or truncated trajectory file (not an .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            missing = {"format", "version", "metadata", *ARRAY_KEYS} - set(archive.files)
            if missing:
                raise RankGameError(f"{path}: not a rankgame trajectory file (missing {', '.join(sorted(missing))})")
            arrays = {key: archive[key] for key in ("format", "version", "metadata", *ARRAY_KEYS)}
    except RankGameError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise RankGameError(f"{path}: unreadable or truncated trajectory file ({exc})") from None
    if str(arrays["format"]) != FORMAT_NAME:
        raise RankGameError(f"{path}: not a rankgame trajectory file (format {str(arrays['format'])!r})")
    version = int(arrays["version"])
    if version != FORMAT_VERSION:
        raise RankGameError(f"{path}: format version {version} is not supported (this rankgame reads {FORMAT_VERSION})")
    try:
        metadata = json.loads(str(arrays["metadata"]))
    except json.JSONDecodeError as exc:
        raise RankGameError(f"{path}: corrupt metadata ({exc})") from None
    file_env = metadata.get("env_id")
    if env_id is not None and file_env != env_id:
        raise RankGameError(f"{path}: trajectories were recorded on {file_env}, not {env_id}")
    try:
        trajectories = _split_episodes(arrays)
    except ValueError as exc:
        raise RankGameError(f"{path}: {exc}") from None
    dims = (trajectories[0].obs.shape[1], trajectories[0].acts.shape[1])
    if (metadata.get("obs_dim"), metadata.get("act_dim")) != dims:
        raise RankGameError(
            f"{path}: arrays have obs_dim={dims[0]}, act_dim={dims[1]} but metadata says "
            f"obs_dim={metadata.get('obs_dim')}, act_dim={metadata.get('act_dim')}"
        )
    return TrajectoryFile(env_id=str(file_env), trajectories=tuple(trajectories), metadata=metadata)


def _split_episodes(arrays: dict[str, np.ndarray]) -> list[Trajectory]:
    """Cut the concatenated arrays back into episodes, checking every size."""
    lengths = arrays["lengths"]
    if lengths.ndim != 1 or len(lengths) == 0:
        raise ValueError("the file holds no episodes")
    if np.any(lengths <= 0):
        raise ValueError("episode lengths must be positive")
    n_steps, n_eps = int(lengths.sum()), len(lengths)
    if arrays["obs"].ndim != 2 or arrays["acts"].ndim != 2:
        raise ValueError("obs and acts must be 2-D arrays")
    if arrays["obs"].shape[0] != n_steps + n_eps:
        raise ValueError(f"obs has {arrays['obs'].shape[0]} rows; the episode lengths need {n_steps + n_eps}")
    for key in ("acts", "rews", "terminated", "truncated"):
        if arrays[key].shape[0] != n_steps:
            raise ValueError(f"{key} has {arrays[key].shape[0]} rows; the episode lengths need {n_steps}")
    step_starts = np.concatenate([[0], np.cumsum(lengths)])
    trajectories = []
    for i in range(n_eps):
        s0, s1 = step_starts[i], step_starts[i + 1]
        o0 = s0 + i
        trajectories.append(
            Trajectory(
                obs=arrays["obs"][o0 : o0 + lengths[i] + 1],
                acts=arrays["acts"][s0:s1],
                rews=arrays["rews"][s0:s1],
                terminated=arrays["terminated"][s0:s1].astype(bool),
                truncated=arrays["truncated"][s0:s1].astype(bool),
            )
        )
    return trajectories
