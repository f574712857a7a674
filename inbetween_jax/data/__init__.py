"""Data layer: BVH I/O, skeletons, windows, features and datasets.

Names are imported on first use (``from inbetween_jax.data import read_bvh`` works as usual), so that importing
a light submodule such as :mod:`inbetween_jax.data.user_input` does not import JAX.
"""
import importlib

_NAMES = {
    "BVHError": "bvh", "Motion": "bvh", "read_bvh": "bvh", "write_bvh": "bvh",
    "load_dataset": "datasets", "load_motions": "datasets", "resolve_source": "datasets",
    "Normalizer": "features", "foot_contacts": "features", "l2p_stats": "features", "root_velocity": "features",
    "Skeleton": "skeleton",
    "MotionWindows": "windows", "canonicalize": "windows", "windows_from_motions": "windows",
}
__all__ = sorted(_NAMES)


def __getattr__(name):
    if name in _NAMES:
        return getattr(importlib.import_module(f"inbetween_jax.data.{_NAMES[name]}"), name)
    raise AttributeError(f"module 'inbetween_jax.data' has no attribute {name!r}")
