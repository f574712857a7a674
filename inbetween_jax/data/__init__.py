"""Data layer: BVH I/O, skeletons, windows, features and datasets."""
from inbetween_jax.data.bvh import BVHError, Motion, read_bvh, write_bvh  # noqa: F401
from inbetween_jax.data.datasets import load_dataset, load_motions, resolve_source  # noqa: F401
from inbetween_jax.data.features import Normalizer, foot_contacts, l2p_stats, root_velocity  # noqa: F401
from inbetween_jax.data.skeleton import Skeleton  # noqa: F401
from inbetween_jax.data.windows import MotionWindows, canonicalize, windows_from_motions  # noqa: F401
