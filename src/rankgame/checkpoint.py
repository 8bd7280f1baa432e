"""Checkpoints: pytrees, NumPy arrays and JSON metadata in one ``.npz``, written atomically.

A run killed at any moment (even ``kill -9``) leaves either the previous checkpoint or the new one,
never a half-written file.
"""

from __future__ import annotations

import json
import sys
import zipfile
from collections.abc import Collection
from pathlib import Path
from typing import Any

import jax
import numpy as np

from rankgame.atomic import atomic_write
from rankgame.errors import RankGameError

#: File name of a run's checkpoint inside its output folder.
CHECKPOINT_NAME = "checkpoint.npz"

#: Options a resumed run may change: how long it goes, how often it evaluates and checkpoints, what
#: it records at the end, where its folder is and what it displays. All others must match.
RUN_CONTROL_OPTIONS = frozenset(
    {
        "steps",
        "out",
        "resume",
        "progress",
        "tensorboard",
        "eval_every",
        "eval_episodes",
        "checkpoint_every",
        "trajectories",
        "random_episodes",
    }
)


def _is_key(leaf: Any) -> bool:
    return isinstance(leaf, jax.Array) and jax.dtypes.issubdtype(leaf.dtype, jax.dtypes.prng_key)


def flatten_tree(prefix: str, tree: Any) -> dict[str, np.ndarray]:
    """Leaves of ``tree`` as ``{f"{prefix}/{i}": array}`` (PRNG keys stored as their raw data)."""
    leaves = jax.tree.leaves(tree)
    return {f"{prefix}/{i}": np.asarray(jax.random.key_data(x) if _is_key(x) else x) for i, x in enumerate(leaves)}


def unflatten_tree(prefix: str, arrays: dict[str, np.ndarray], template: Any) -> Any:
    """Inverse of :func:`flatten_tree`, using ``template`` for structure, dtypes and key types."""
    leaves, treedef = jax.tree.flatten(template)
    restored = []
    for i, like in enumerate(leaves):
        if f"{prefix}/{i}" not in arrays:
            raise RankGameError(f"checkpoint does not match this configuration ({prefix} leaf {i} is missing)")
        value = arrays[f"{prefix}/{i}"]
        if _is_key(like):
            restored.append(jax.random.wrap_key_data(value, impl=jax.random.key_impl(like)))
        else:
            if value.shape != np.shape(like):
                raise RankGameError(f"checkpoint does not match this configuration ({prefix} leaf {i}: {value.shape})")
            restored.append(jax.numpy.asarray(value, dtype=like.dtype))
    return jax.tree.unflatten(treedef, restored)


def save_checkpoint(path: Path, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` and JSON ``metadata`` atomically to ``path``."""
    payload = {"metadata": np.asarray(json.dumps(metadata)), **arrays}
    atomic_write(path, lambda handle: np.savez(handle, **payload))


def load_checkpoint(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read a checkpoint written by :func:`save_checkpoint`."""
    if not path.is_file():
        raise RankGameError(f"no checkpoint to resume from at {path}")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {key: archive[key] for key in archive.files}
        metadata = json.loads(str(arrays.pop("metadata")))
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise RankGameError(f"{path}: unreadable checkpoint ({exc})") from None
    return metadata, arrays


def make_out_dir(out: Path) -> None:
    """Create the run folder ``out`` (and its parents), or raise a one-line error saying why not."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RankGameError(f"cannot create the output folder {out}: {exc.strerror}") from None


def checkpoint_to_resume(out: Path, resume: bool) -> Path | None:
    """The checkpoint a run in ``out`` continues from, or None when it starts at step 0.

    Without ``resume`` a folder that already holds a run is refused. With it, the run continues from
    its checkpoint; a run stopped before it wrote its first checkpoint has nothing to continue from and
    starts again at step 0 (its logged rows are dropped by the logger). A folder with no run in it is
    refused, since ``--resume`` there most likely names the wrong folder.
    """
    ckpt = out / CHECKPOINT_NAME
    started = (out / "metrics.csv").exists()
    if not resume:
        if started or ckpt.exists():
            raise RankGameError(f"{out} already holds a run; pass --resume to continue it or choose another --out")
        return None
    if ckpt.exists():
        return ckpt
    if started:
        print(f"{out}: the run stopped before its first checkpoint; starting it again at step 0", file=sys.stderr)
        return None
    raise RankGameError(f"no checkpoint to resume from at {ckpt}")


def load_run_checkpoint(
    path: Path, config: dict[str, Any], defaults: dict[str, Any], steps: int
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Load the checkpoint a run resumes from, refusing changed settings or a ``--steps`` it has passed.

    ``config`` is the resumed run's config as JSON and ``defaults`` the default config of its command;
    see :func:`require_same_settings`.
    """
    metadata, arrays = load_checkpoint(path)
    if not isinstance(metadata, dict) or not {"config", "env_steps"} <= metadata.keys():
        raise RankGameError(f"{path}: not a checkpoint of a rankgame run (no config or step count)")
    require_same_settings(metadata["config"], config, RUN_CONTROL_OPTIONS, defaults)
    if steps < int(metadata["env_steps"]):
        raise RankGameError(f"--steps {steps} is below the checkpoint's {metadata['env_steps']} steps")
    return metadata, arrays


def require_same_settings(
    saved: dict[str, Any], current: dict[str, Any], may_change: Collection[str], defaults: dict[str, Any] | None = None
) -> None:
    """Refuse to resume with settings other than the checkpoint's.

    ``saved`` and ``current`` are a run's config as JSON (nested dicts for ``sac`` and ``reward``);
    every option must be equal except the top-level ones in ``may_change`` (how long the run goes,
    how often it evaluates and checkpoints, what it displays). An option the checkpoint does not record
    (one added in a later version of rankgame) is accepted at its value in ``defaults``, the behaviour
    of the version that wrote the checkpoint. Raises :class:`RankGameError` naming the first option
    that differs.
    """
    flat_saved, flat_current = _flatten_options(saved), _flatten_options(current)
    flat_defaults = _flatten_options(defaults or {})
    for name in sorted(set(flat_saved) | set(flat_current)):
        if name.split(".")[0] in may_change:
            continue
        if name not in flat_saved and name in flat_defaults and flat_current.get(name) == flat_defaults[name]:
            continue
        was, now = flat_saved.get(name), flat_current.get(name)
        if was != now:
            option = "--" + name.replace("_", "-")
            raise RankGameError(
                f"{option} {_shown(now)} differs from the checkpoint's {_shown(was)}; a resumed run keeps its settings"
            )


def _flatten_options(config: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in config.items():
        if isinstance(value, dict):
            flat.update(_flatten_options(value, f"{prefix}{key}."))
        else:
            flat[prefix + key] = value
    return flat


def _shown(value: Any) -> str:
    if value is None:
        return "(not given)"
    return " ".join(map(str, value)) if isinstance(value, list) else str(value)
