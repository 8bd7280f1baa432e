"""The one exception type the command line turns into a one-line message and a non-zero exit."""

from __future__ import annotations

import dataclasses
import math
from typing import Any


class RankGameError(Exception):
    """A problem with user input (arguments, data files, environments) explained in one line."""


def require(checks: list[tuple[bool, str]]) -> None:
    """Raise ``ValueError`` with the message of the first check that failed."""
    for ok, message in checks:
        if not ok:
            raise ValueError(message)


def nonfinite_fields(config: Any) -> list[str]:
    """Names of the float fields of the dataclass instance ``config`` that hold NaN or infinity."""
    return [
        f.name
        for f in dataclasses.fields(config)
        if isinstance(getattr(config, f.name), float) and not math.isfinite(getattr(config, f.name))
    ]
