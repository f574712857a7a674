"""Evaluation metrics, one family per module (pure jnp, jit-able, batched).

positions: L2P, ADE, FDE, SLDE, MPJPE (mean, std); quaternions: L2Q; npss: NPSS;
diversity: APD; foot: foot sliding / foot skating; stitching: MMPE; bones: bone-length spread; frechet: Frechet
distance of feature sets (NumPy / SciPy, not jitted).
Every public function but ``frechet_distance`` is already wrapped in ``jax.jit`` (integer / bool options
such as ``up_axis``, ``root_index``, ``root_relative``, ``mid_index`` are static); arrays may be NumPy or JAX,
results are float32 JAX scalars (``mpjpe`` returns a ``(mean, std)`` pair).
"""
from inbetween_jax.metrics.positions import ade, fde, joint_distances, l2p, mpjpe, slde  # noqa: F401
from inbetween_jax.metrics.quaternions import l2q  # noqa: F401
from inbetween_jax.metrics.npss import fast_npss, npss  # noqa: F401
from inbetween_jax.metrics.diversity import apd  # noqa: F401
from inbetween_jax.metrics.foot import (  # noqa: F401
    foot_heights, foot_skating, foot_skating_frames, foot_skating_weight, foot_sliding,
    foot_sliding_frames, horizontal_displacement)
from inbetween_jax.metrics.stitching import mmpe  # noqa: F401
from inbetween_jax.metrics.bones import bone_length_spread  # noqa: F401
from inbetween_jax.metrics.frechet import frechet_distance  # noqa: F401

__all__ = ["ade", "fde", "slde", "l2p", "mpjpe", "joint_distances", "l2q", "npss", "fast_npss", "apd",
           "foot_heights", "horizontal_displacement", "foot_sliding_frames", "foot_sliding",
           "foot_skating_weight", "foot_skating_frames", "foot_skating", "mmpe", "bone_length_spread",
           "frechet_distance"]
