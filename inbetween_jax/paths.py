"""Where the package keeps its caches: one root for window caches and compiled executables."""
from __future__ import annotations

import os

__all__ = ["CACHE_ENV", "cache_root"]

CACHE_ENV = "INBETWEEN_JAX_CACHE"


def cache_root() -> str:
    """``$INBETWEEN_JAX_CACHE`` (default ``~/.cache/inbetween_jax``), absolute: window caches live here and
    compiled executables in its ``jax_cache`` sub-folder."""
    return os.path.abspath(os.path.expanduser(os.environ.get(CACHE_ENV) or os.path.join("~", ".cache",
                                                                                       "inbetween_jax")))
