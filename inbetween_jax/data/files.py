"""BVH file lists below every source: the embedded clips' folder and splits, a folder's BVH files, and the
file-reading progress bar.

:mod:`inbetween_jax.data.sources` (the ``cmu`` source, built on the embedded files) and
:mod:`inbetween_jax.data.datasets` (every source's splits) both use these; this module imports neither.
"""
from __future__ import annotations

import os
import sys

EMBEDDED_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "assets", "cmu30")
EMBEDDED_TEST_PREFIXES = ("13_", "14_")

__all__ = ["EMBEDDED_DIR", "EMBEDDED_TEST_PREFIXES", "bvh_files", "embedded_files", "progress"]


def bvh_files(folder: str) -> list:
    """The ``.bvh`` files of ``folder``, sorted by name (FileNotFoundError when there is no folder or no file)."""
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"data folder {folder!r} does not exist")
    files = sorted(os.path.join(folder, f) for f in os.listdir(folder) if f.lower().endswith(".bvh"))
    if not files:
        raise FileNotFoundError(f"no .bvh files in {folder!r}")
    return files


def embedded_files(split: str) -> list:
    """The embedded clips of ``split``: ``train``, or ``test`` / ``benchmark`` (CMU subjects 13 and 14)."""
    files = bvh_files(EMBEDDED_DIR)
    test = [f for f in files if os.path.basename(f).startswith(EMBEDDED_TEST_PREFIXES)]
    return test if split != "train" else [f for f in files if f not in test]


def progress(items, desc):
    """A file-reading progress bar, only on a terminal (a log file gets no carriage-return noise)."""
    try:
        from tqdm import tqdm
        return tqdm(items, desc=desc, leave=False, disable=len(items) < 4 or not sys.stderr.isatty())
    except ImportError:  # pragma: no cover
        return items
