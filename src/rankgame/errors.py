"""The exceptions the command line turns into a one-line message and a non-zero exit status."""

from __future__ import annotations

import dataclasses
import math
from typing import Any


class RankGameError(Exception):
    """A problem with user input (arguments, data files, environments) explained in one line."""


class NonFiniteError(RankGameError):
    """Training produced a NaN or infinite value (a loss, a parameter, an action): the run must stop.

    ``quantity`` names what was not finite; the run harness adds the step and the last good checkpoint.
    """

    def __init__(self, quantity: str) -> None:
        super().__init__(f"{quantity} is not finite")
        self.quantity = quantity


class RunInterrupted(RankGameError):
    """A run stopped by a signal after writing its checkpoint; ``signal_number`` is SIGINT's or SIGTERM's."""

    def __init__(self, message: str, signal_number: int) -> None:
        super().__init__(message)
        self.signal_number = signal_number


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
