"""Files of one msgpack payload with a JSON ``header`` that names their format and version (saved
policies, exported rewards)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import flax.serialization

from rankgame.errors import RankGameError


def read_header_file(path: str | Path, what: str, file_format: str, version: int) -> tuple[dict[str, Any], dict]:
    """The payload and decoded header of a file written as ``{"header": json, ...}``; a one-line
    :class:`RankGameError` (naming ``what``, e.g. ``policy``) for a missing, corrupt or foreign file."""
    path = Path(path)
    if not path.is_file():
        raise RankGameError(f"{what} file not found: {path}")
    try:
        payload = flax.serialization.msgpack_restore(path.read_bytes())
        header = json.loads(payload["header"])
    except Exception as exc:  # msgpack raises several unrelated types on corrupt input
        raise RankGameError(f"{path}: unreadable or truncated {what} file ({type(exc).__name__})") from None
    if not isinstance(header, dict) or header.get("format") != file_format or header.get("version") != version:
        raise RankGameError(f"{path}: not a rankgame {what} file of version {version}")
    return payload, header
