"""Where the package keeps its caches, and where the larger shared mocap folder (the ``cmu`` source) lives."""
from __future__ import annotations

import os
from typing import Optional

__all__ = ["CACHE_ENV", "SHARED_DATA_ENV", "cache_root", "shared_data_dir"]

CACHE_ENV = "INBETWEEN_JAX_CACHE"
SHARED_DATA_ENV = "INBETWEEN_SHARED_DATA"
_REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cache_root() -> str:
    """``$INBETWEEN_JAX_CACHE`` (default ``~/.cache/inbetween_jax``), absolute: window caches live here and
    compiled executables in its ``jax_cache`` sub-folder."""
    return os.path.abspath(os.path.expanduser(os.environ.get(CACHE_ENV) or os.path.join("~", ".cache",
                                                                                       "inbetween_jax")))


def shared_data_dir(required: bool = False) -> Optional[str]:
    """The shared mocap folder (holding ``cmu_bvh/``, ``cmu_more/``, ``cmu_pairs/``), absolute:
    ``$INBETWEEN_SHARED_DATA`` if set, else ``<repository root>/../shared/data`` if that folder exists.

    Returns None when neither is there, or raises a one-line
    :class:`~inbetween_jax.errors.UserError` saying what to set when ``required``.
    """
    env = os.environ.get(SHARED_DATA_ENV)
    path = os.path.abspath(os.path.expanduser(env)) if env else os.path.join(os.path.dirname(_REPO_ROOT),
                                                                             "shared", "data")
    if os.path.isdir(path):
        return path
    if required:
        from inbetween_jax.errors import UserError
        where = f"${SHARED_DATA_ENV}={env} is not a folder" if env else f"{path} not found"
        raise UserError(f"the cmu source needs the shared mocap folder ({where}): set {SHARED_DATA_ENV} to the "
                        "folder holding cmu_bvh/, cmu_more/daz43/, cmu_more/mb31/ and cmu_pairs/")
    return None
