"""The one exception type the command line turns into a one-line message and a non-zero exit."""


class RankGameError(Exception):
    """A problem with user input (arguments, data files, environments) explained in one line."""


def require(checks: list[tuple[bool, str]]) -> None:
    """Raise ``ValueError`` with the message of the first check that failed."""
    for ok, message in checks:
        if not ok:
            raise ValueError(message)
