"""Data shipped with rankgame: one ``<env_id>.npz`` trajectory file per task in a package folder.

A namespaced id names its file with ``__`` for the ``/``: ``rankgame/HopperBackward-v5`` is
``rankgame__HopperBackward-v5.npz``.
"""

from __future__ import annotations

from pathlib import Path

from rankgame.errors import RankGameError


def shipped_ids(folder: Path) -> list[str]:
    """Environment ids with a file in ``folder``, sorted."""
    return sorted(path.stem.replace("__", "/") for path in folder.glob("*.npz"))


def shipped_path(folder: Path, env_id: str, what: str, instead: str, available: list[str] | None = None) -> Path:
    """``folder/<env_id>.npz``, or a :class:`RankGameError` naming the ids that have ``what`` (``available``,
    every id whose data resolves; default: those with a file in ``folder``) and what to do ``instead``."""
    path = folder / f"{env_id.replace('/', '__')}.npz"
    if not path.is_file():
        names = ", ".join(shipped_ids(folder) if available is None else available) or "none"
        raise RankGameError(f"no shipped {what} for {env_id!r} (available: {names}); {instead}")
    return path
