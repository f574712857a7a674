"""Errors that reach users as one line (``inbetween: error: ...``, exit status 2)."""

__all__ = ["UserError"]


class UserError(Exception):
    """A problem with the user's inputs; ``str(err)`` is the one-line message."""
