"""Errors of the command line."""

__all__ = ["CLIError"]


class CLIError(Exception):
    """A user error to report on one line with exit code 2."""
