"""What the benchmark scripts share at their edges: a one-line refusal of bad settings, and the JSON
result printed and, with ``--out``, written atomically."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rankgame.atomic import atomic_write_bytes


def refused(script: str, problems: Iterable[tuple[bool, str]]) -> bool:
    """Print ``SCRIPT: MESSAGE`` to stderr for the first ``(bad, message)`` that is bad; whether one was."""
    for bad, message in problems:
        if bad:
            print(f"{script}: {message}", file=sys.stderr)
            return True
    return False


def emit(result: dict[str, Any], out: Path | None) -> None:
    """Print ``result`` as indented JSON and, with ``out``, write the same text there (atomically)."""
    text = json.dumps(result, indent=2)
    if out is not None:
        atomic_write_bytes(out, (text + "\n").encode())
    print(text)
