"""Rotation metric: L2Q of the LaFAN1 benchmark (pure ``jax.numpy``, ``jit``-able)."""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["l2q"]


@jax.jit
def l2q(pred_quats, gt_quats):
    """L2Q: the LaFAN1 benchmark's global-quaternion error, exactly ``lafan1/benchmarks.py``:

        L2Q = mean_{b,t} sqrt( sum_{j, c} (pred[b,t,j,c] - gt[b,t,j,c])^2 )

    pred_quats, gt_quats: (..., T, J, 4) *global* quaternions (w, x, y, z) of the transition frames.
    The plain difference is sign sensitive (q and -q are the same rotation), so, as in the official
    pipeline, the quaternions must be sign-continuous over time: LaFAN1 applies the hemisphere fix
    (``inbetween_jax.geometry.quat_fix_sign`` along time) to the local quaternions of the whole
    window before FK, and predictions are expected to follow the same convention. This function
    does not alter the signs. Returns a scalar, unitless.
    """
    pred_quats = jnp.asarray(pred_quats)
    gt_quats = jnp.asarray(gt_quats)
    return jnp.mean(jnp.sqrt(jnp.sum((pred_quats - gt_quats) ** 2, axis=(-2, -1))))
