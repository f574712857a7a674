"""Interpolation baseline of the official LaFAN1 benchmark: root lerp, local-quaternion slerp."""
from __future__ import annotations

from inbetween_jax.geometry.quaternion import _xp, quat_normalize, quat_slerp


def interpolate_transition(local_quats, root_pos, n_past: int, n_trans: int):
    """Interpolate between frame ``n_past - 1`` (last past keyframe) and frame ``n_past + n_trans``
    (target keyframe) as ``benchmarks.interpolate_local`` does: weights ``linspace(0, 1, n_trans + 2)``
    with the two keyframes dropped.

    local_quats: (B, T, J, 4); root_pos: (B, T, 3) with T > n_past + n_trans.
    Returns (trans_quats (B, n_trans, J, 4), trans_root (B, n_trans, 3)).
    """
    xp = _xp(local_quats, root_pos)
    start_q = quat_normalize(local_quats[:, n_past - 1], eps=0.0)[:, None]
    end_q = quat_normalize(local_quats[:, n_past + n_trans], eps=0.0)[:, None]
    start_r = root_pos[:, n_past - 1][:, None]
    end_r = root_pos[:, n_past + n_trans][:, None]
    w = xp.linspace(0.0, 1.0, n_trans + 2)[1:-1].astype(root_pos.dtype)
    root = start_r + w[None, :, None] * (end_r - start_r)
    quats = quat_slerp(start_q, end_q, w[None, :, None])
    return quats, root
