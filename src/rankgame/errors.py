"""The one exception type the command line turns into a one-line message and a non-zero exit."""


class RankGameError(Exception):
    """A problem with user input (arguments, data files, environments) explained in one line."""
