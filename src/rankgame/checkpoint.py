"""Checkpoints: pytrees, NumPy arrays and JSON metadata in one ``.npz``, written atomically.

A run killed at any moment (even ``kill -9``) leaves either the previous checkpoint or the new one,
never a half-written file, and a checkpoint never holds a NaN or infinite array. Arrays are keyed
by their tree path (``sac/actor_params/params/MLP_0/Dense_0/kernel``), so ``numpy.load`` reads a
checkpoint without rankgame; the JSON metadata is the array ``metadata``.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Collection
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rankgame.atomic import atomic_write
from rankgame.errors import NonFiniteError, RankGameError

#: File name of a run's checkpoint inside its output folder.
CHECKPOINT_NAME = "checkpoint.npz"

#: Version of the checkpoint layout (2: arrays keyed by tree path, nested configs); others are refused.
CHECKPOINT_VERSION = 2

#: Options a resumed run may change: how long it goes, how often it evaluates and checkpoints, what
#: it records at the end, where its folder is and what it displays. All others are the run's own.
RUN_CONTROL_OPTIONS = frozenset(
    {
        "steps",
        "out",
        "resume",
        "progress",
        "tensorboard",
        "wandb",
        "eval_every",
        "eval_episodes",
        "checkpoint_every",
        "trajectories",
        "random_episodes",
    }
)


def _is_key(leaf: Any) -> bool:
    return isinstance(leaf, jax.Array) and jax.dtypes.issubdtype(leaf.dtype, jax.dtypes.prng_key)


def _path_name(path: tuple[Any, ...]) -> str:
    """``a/b/0`` for a tree path of dict keys, attribute names and sequence indices."""
    parts = []
    for entry in path:
        for attribute in ("key", "name", "idx"):
            if hasattr(entry, attribute):
                parts.append(str(getattr(entry, attribute)))
                break
        else:
            parts.append(str(entry))
    return "/".join(parts)


def _leaves_by_name(prefix: str, tree: Any) -> dict[str, Any]:
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    return {f"{prefix}/{_path_name(path)}" if path else prefix: leaf for path, leaf in leaves}


def flatten_tree(prefix: str, tree: Any) -> dict[str, np.ndarray]:
    """Leaves of ``tree`` as ``{f"{prefix}/{tree path}": array}`` (PRNG keys stored as their raw data)."""
    return {
        name: np.asarray(jax.random.key_data(leaf) if _is_key(leaf) else leaf)
        for name, leaf in _leaves_by_name(prefix, tree).items()
    }


def unflatten_tree(prefix: str, arrays: dict[str, np.ndarray], template: Any) -> Any:
    """Inverse of :func:`flatten_tree`, using ``template`` for structure, dtypes and key types."""
    restored = []
    for name, like in _leaves_by_name(prefix, template).items():
        if name not in arrays:
            raise RankGameError(f"the checkpoint does not match this configuration ({name} is missing)")
        value = arrays[name]
        if _is_key(like):
            restored.append(jax.random.wrap_key_data(value, impl=jax.random.key_impl(like)))
            continue
        if value.shape != np.shape(like):
            raise RankGameError(f"the checkpoint does not match this configuration ({name} has shape {value.shape})")
        restored.append(jax.numpy.asarray(value, dtype=like.dtype))
    return jax.tree.unflatten(jax.tree.structure(template), restored)


def require_finite(arrays: dict[str, np.ndarray]) -> None:
    """Raise :class:`NonFiniteError` naming the first floating-point array with a NaN or infinity."""
    for name, array in arrays.items():
        if np.issubdtype(array.dtype, np.floating) and not np.all(np.isfinite(array)):
            raise NonFiniteError(name)


def save_checkpoint(path: Path, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` and JSON ``metadata`` atomically to ``path``; arrays must be finite."""
    require_finite(arrays)
    payload = {"metadata": np.asarray(json.dumps({**metadata, "checkpoint_version": CHECKPOINT_VERSION})), **arrays}
    atomic_write(path, lambda handle: np.savez(handle, **payload))


def load_checkpoint(path: Path, any_layout: bool = False) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read a checkpoint written by :func:`save_checkpoint`; one of another layout only with ``any_layout``
    (for readers of arrays whose keys every layout shares, such as the replay buffer's)."""
    if not path.is_file():
        raise RankGameError(f"no checkpoint to resume from at {path}")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {key: archive[key] for key in archive.files}
        metadata = json.loads(str(arrays.pop("metadata")))
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise RankGameError(f"{path}: unreadable checkpoint ({exc})") from None
    if not isinstance(metadata, dict) or not {"config", "env_steps"} <= metadata.keys():
        raise RankGameError(f"{path}: not a checkpoint of a rankgame run (no config or step count)")
    version = metadata.get("checkpoint_version", 1)
    if version != CHECKPOINT_VERSION and not any_layout:
        raise RankGameError(
            f"{path} has checkpoint layout {version}; this rankgame reads layout {CHECKPOINT_VERSION}: start the run "
            "again in another folder"
        )
    return metadata, arrays


def require_same_settings(saved: dict[str, Any], current: dict[str, Any], may_change: Collection[str]) -> None:
    """Refuse to resume with settings other than the checkpoint's.

    ``saved`` and ``current`` are a run's config as JSON (nested dicts for the nested configs); every
    option must be equal except the top-level ones in ``may_change``. Raises :class:`RankGameError`
    naming the first option that differs.
    """
    flat_saved, flat_current = flatten_options(saved), flatten_options(current)
    for name in sorted(set(flat_saved) | set(flat_current)):
        if name.split(".")[0] in may_change:
            continue
        was, now = flat_saved.get(name), flat_current.get(name)
        if was != now:
            raise RankGameError(
                f"{option_name(name)} {_shown(now)} differs from the run's {_shown(was)}; a resumed run keeps its "
                "settings"
            )


def flatten_options(config: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """A config as JSON, flattened to dotted option names: ``{"reward.lr": 0.001, ...}``."""
    flat: dict[str, Any] = {}
    for key, value in config.items():
        if isinstance(value, dict):
            flat.update(flatten_options(value, f"{prefix}{key}."))
        else:
            flat[prefix + key] = value
    return flat


def option_name(name: str) -> str:
    """The command-line spelling of a dotted option name: ``reward.r_max`` -> ``--reward.r-max``."""
    return "--" + name.replace("_", "-")


def _shown(value: Any) -> str:
    if value is None:
        return "(not given)"
    return " ".join(map(str, value)) if isinstance(value, list) else str(value)
