"""Errors that reach users as one line (``inbetween: error: ...``, exit status 2)."""
import zipfile

__all__ = ["UserError", "NPZ_READ_ERRORS"]

# What ``np.load`` raises on a missing, empty, cut-short or foreign ``.npz`` file: readers catch these (and
# KeyError for a missing array) and raise one line naming the file.
NPZ_READ_ERRORS = (OSError, ValueError, EOFError, zipfile.BadZipFile)


class UserError(Exception):
    """A problem with the user's inputs; ``str(err)`` is the one-line message."""
