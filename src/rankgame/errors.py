"""The exceptions the command line turns into a one-line message and a non-zero exit status."""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from typing import Any, Literal


class RankGameError(Exception):
    """A problem with user input (arguments, data files, environments) explained in one line."""


class UsageError(RankGameError):
    """A command line that is itself wrong (an unknown choice of an option read ahead of parsing, such as
    ``--preset`` or ``--recipe``): exit status 2, as for argparse's own errors."""


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


def invalid_choices(config: Any, prefix: str = "") -> list[str]:
    """``name=value (choose from ...)`` for every field of the dataclass instance ``config``, nested
    dataclasses included, whose ``Literal`` annotation does not admit its value (the command line's
    choices check this; configs built in Python are checked here)."""
    hints = typing.get_type_hints(type(config))
    problems = []
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if dataclasses.is_dataclass(value):
            problems += invalid_choices(value, f"{prefix}{f.name}.")
            continue
        annotation = hints[f.name]
        if typing.get_origin(annotation) in (typing.Union, types.UnionType):  # Optional[Literal[...]]
            if value is None:
                continue
            annotation = next((a for a in typing.get_args(annotation) if typing.get_origin(a) is Literal), None)
        if typing.get_origin(annotation) is Literal and value not in typing.get_args(annotation):
            choices = ", ".join(map(str, typing.get_args(annotation)))
            problems.append(f"{prefix}{f.name}={value!r} (choose from {choices})")
    return problems
