"""Expert trajectories shipped with rankgame, one ``<env_id>.npz`` file per task.

Each file was written by ``rankgame expert`` (its metadata keeps the exact command, seed and
library versions) and also records the mean return of a uniformly random policy, so that scores
can be normalized as ``100 (R - R_random) / (R_expert - R_random)``. A variant task that observes only
the leading entries of another (``rankgame/AntNoContact-v5``) uses that task's file with the other
entries left out.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rankgame.data import shipped_ids, shipped_path
from rankgame.data.minari import is_minari_ref, minari_dataset_id, read_minari
from rankgame.data.trajectories import TrajectoryFile, load_trajectories
from rankgame.envs.variants import OBS_PREFIX_VARIANTS

EXPERT_DIR = Path(__file__).parent


def shipped_envs() -> list[str]:
    """Environment ids with shipped expert data, sorted (variants of a task with shipped data included)."""
    ids = shipped_ids(EXPERT_DIR)
    return sorted([*ids, *(env_id for env_id, (source, _) in OBS_PREFIX_VARIANTS.items() if source in ids)])


def shipped_expert_path(env_id: str) -> Path:
    """The shipped file that holds the expert data of ``env_id`` (for a variant, that of its source task);
    a :class:`~rankgame.errors.RankGameError` if there is none."""
    source_id = OBS_PREFIX_VARIANTS.get(env_id, (env_id, 0))[0]
    return shipped_path(EXPERT_DIR, source_id, "expert data", "pass your own file", shipped_envs())


def load_shipped_expert(env_id: str) -> TrajectoryFile:
    """Load and validate the shipped expert trajectories of ``env_id``."""
    if env_id in OBS_PREFIX_VARIANTS:
        source_id, n_obs = OBS_PREFIX_VARIANTS[env_id]
        return load_shipped_expert(source_id).with_leading_obs(n_obs, env_id)
    return load_trajectories(shipped_expert_path(env_id), env_id=env_id)


def load_expert_data(path: Path | str | None, env_id: str) -> TrajectoryFile:
    """Expert data recorded on ``env_id``: the file at ``path``, the local Minari dataset it names as
    ``minari:DATASET_ID``, or the shipped data when ``path`` is None."""
    if path is None:
        return load_shipped_expert(env_id)
    if is_minari_ref(path):
        return read_minari(minari_dataset_id(path), env_id)
    return load_trajectories(path, env_id=env_id)


def normalized_score(ret: float | np.ndarray, expert_return: float, random_return: float) -> float | np.ndarray:
    """``100 (R - R_random) / (R_expert - R_random)``: 0 is random, 100 is the expert.

    Undefined (NaN) when the expert's return equals the random return, as in data with all-zero rewards.
    """
    ret = np.asarray(ret, np.float64)
    if expert_return == random_return:
        return np.full_like(ret, np.nan)
    return 100.0 * (ret - random_return) / (expert_return - random_return)


def expert_summary(data: TrajectoryFile) -> dict[str, Any]:
    """One row of ``rankgame experts``: counts, lengths, returns and the random return."""
    returns = data.returns
    return {
        "env": data.env_id,
        "trajectories": len(data.trajectories),
        "mean_length": float(np.mean([len(t) for t in data.trajectories])),
        "return_mean": float(returns.mean()),
        "return_std": float(returns.std()),
        "random_return": float(data.metadata.get("random_return_mean", float("nan"))),
        "command": data.metadata.get("command", ""),
    }


def expert_table() -> list[dict[str, Any]]:
    """Summaries of every shipped expert file."""
    return [expert_summary(load_shipped_expert(env_id)) for env_id in shipped_envs()]
