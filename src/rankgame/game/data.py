"""The data a ranking game imitates, resolved from paths or memory and checked once.

Expert data and preferences may be given as a file path (``minari:DATASET_ID`` for a local Minari
dataset), as a :class:`~rankgame.data.trajectories.TrajectoryFile`, or as a sequence of
:class:`~rankgame.data.trajectories.Trajectory` (in memory); None means the data shipped for the task.
Every mismatch (task, dimensions, too few trajectories) is a one-line
:class:`~rankgame.errors.RankGameError`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rankgame.data.experts import load_expert_data
from rankgame.data.preferences import load_preferences, ranking_order, shipped_preferences_path
from rankgame.data.trajectories import Trajectory, TrajectoryFile
from rankgame.envs.make import EnvSpec
from rankgame.errors import RankGameError

#: Trajectory data as the API accepts it: a path, a trajectory file, trajectories in memory, or None.
DataSource = str | Path | TrajectoryFile | Sequence[Trajectory] | None


@dataclass(frozen=True)
class Preferences:
    """Offline trajectories and their worst-to-best order ``(p,)``."""

    data: TrajectoryFile
    order: np.ndarray

    @property
    def ranked(self) -> list[Trajectory]:
        """The trajectories, worst first."""
        return [self.data.trajectories[i] for i in self.order]


def _in_memory(source: TrajectoryFile | Sequence[Trajectory], env_id: str, what: str) -> TrajectoryFile:
    if isinstance(source, TrajectoryFile):
        if source.env_id != env_id:
            raise RankGameError(f"{what} was recorded on {source.env_id}, not {env_id}")
        return source
    trajectories = tuple(source)
    if not trajectories or not all(isinstance(t, Trajectory) for t in trajectories):
        raise RankGameError(f"{what} must be a path, a TrajectoryFile or a non-empty sequence of Trajectory")
    return TrajectoryFile(env_id, trajectories, {"env_id": env_id, "source": "memory"})


def _describe(source: DataSource, env_id: str, what: str) -> str:
    if source is None:
        return f"the shipped {what} of {env_id}"
    return str(source) if isinstance(source, str | Path) else f"the {what} given in memory"


def resolve_expert(source: DataSource, env_id: str, spec: EnvSpec, n_trajectories: int, what: str) -> TrajectoryFile:
    """Expert data recorded on ``env_id`` with ``spec``'s dimensions and at least ``n_trajectories``
    trajectories; ``what`` names it in errors (``expert data``, ``--switch.expert data``)."""
    if source is None or isinstance(source, str | Path):
        data = load_expert_data(None if source is None else Path(source), env_id)
    else:
        data = _in_memory(source, env_id, what)
    require_dims(data, spec, what)
    if len(data.trajectories) < n_trajectories:
        raise RankGameError(
            f"{_describe(source, env_id, what)} holds {len(data.trajectories)} trajectories; "
            f"--expert-trajectories asks for {n_trajectories}"
        )
    return data


def resolve_preferences(source: DataSource, env_id: str, spec: EnvSpec) -> Preferences:
    """Offline ranked trajectories for the pref methods (the shipped file of ``env_id`` by default)."""
    if source is None or isinstance(source, str | Path):
        path = Path(source) if source is not None else shipped_preferences_path(env_id)
        data, order = load_preferences(path, env_id)
    else:
        data = _in_memory(source, env_id, "preference data")
        if len(data.trajectories) < 2:
            raise RankGameError("the preference data given in memory holds 1 trajectory; a ranking needs at least 2")
        order = ranking_order(data)
    require_dims(data, spec, "preference data")
    return Preferences(data, order)


def require_dims(data: TrajectoryFile, spec: EnvSpec, what: str) -> None:
    """A one-line error if recorded trajectories do not have the task's dimensions."""
    if (data.obs_dim, data.act_dim) != (spec.obs_dim, spec.act_dim):
        raise RankGameError(
            f"{what} has obs_dim={data.obs_dim}, act_dim={data.act_dim}; {spec.env_id} has "
            f"obs_dim={spec.obs_dim}, act_dim={spec.act_dim}"
        )
