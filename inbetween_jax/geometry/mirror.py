"""Left-right mirror of a pose on any rig whose rest pose is symmetric (NumPy, float64).

A motion mirrored in the world plane ``x = 0`` (normal ``world_axis``, a floor axis for Y-up data) is again a
body's motion: joint ``j`` of the mirror moves as joint ``twin[j]`` (its left/right counterpart, itself for
central joints) seen in a mirror, ``p'_j = M p_twin(j)``.  With ``N`` the reflection of the rig's rest frame
that maps left offsets onto right ones (``o_twin(j) = N o_j``, found by :func:`rest_side_axis`) the global
rotations ``G'_j = M G_twin(j) N`` reproduce exactly those positions, so the local rotations are
``L'_j = N L_twin(j) N`` and the root's ``L'_0 = M G_0 N`` (a proper rotation: ``det M = det N = -1``).

For a reflection ``R`` with normal ``e_a``, ``R Q R`` is the rotation about ``-R u`` by the same angle, i.e. the
quaternion ``(w, v)`` becomes ``(w, -R v)``: the ``a`` component kept, the other two negated.
"""
from __future__ import annotations

import numpy as np

from inbetween_jax.geometry.quaternion import quat_mul

__all__ = ["MIRROR_TAG", "rest_side_axis", "mirror_pose"]

MIRROR_TAG = " (mirrored)"  # the name suffix of a mirror image (a bank clip, a training window)
SYMMETRY_TOL = 0.05    # largest left/right offset mismatch, as a share of the rig's longest bone, to count as symmetric


def rest_side_axis(offsets, twin) -> int:
    """The axis (0, 1 or 2) of the rig's rest frame across which left and right bone offsets mirror.

    offsets: (J, 3) bone offsets; twin: (J,) each joint's left/right counterpart (``Skeleton.mirror_map``).
    Raises ValueError (one line) when the rig has no left/right pair or no axis makes its rest pose
    symmetric within :data:`SYMMETRY_TOL` of its longest bone.
    """
    off = np.asarray(offsets, np.float64)
    twin = np.asarray(twin, np.int64)
    if np.all(twin == np.arange(len(twin))):
        raise ValueError("mirroring needs left/right joints named Left*/Right* (or l*/r*); this rig has none")
    scale = max(float(np.linalg.norm(off[1:], axis=-1).max(initial=0.0)), 1e-12)
    errs = []
    for a in range(3):
        flip = np.ones(3)
        flip[a] = -1.0
        errs.append(float(np.abs(off[twin[1:]] - off[1:] * flip).max()) / scale)
    axis = int(np.argmin(errs))
    if errs[axis] > SYMMETRY_TOL:
        raise ValueError(f"the rig's rest pose is not left-right symmetric (offsets of twin joints differ by "
                         f"{errs[axis]:.0%} of the longest bone across the best axis)")
    return axis


def _reflect_conj(q, axis: int):
    """``R Q R`` for the reflection ``R`` with normal ``e_axis``: (..., 4) -> (..., 4)."""
    sign = -np.ones(4)
    sign[0] = 1.0
    sign[1 + axis] = 1.0
    return q * sign


def mirror_pose(local_quats, root_pos, twin, rest_axis: int, world_axis: int = 0, local_pos=None):
    """The mirror image of a motion: ``(local_quats (..., J, 4), root_pos (..., 3))``, and its local positions
    (..., J, 3) too when ``local_pos`` (row 0 the root's position, the others offsets or animated positions in
    the parent's frame) is given.

    local_quats: (..., J, 4) local rotations (w, x, y, z), joint 0 the root; root_pos: (..., 3); twin: (J,) from
    ``Skeleton.mirror_map``; rest_axis: :func:`rest_side_axis` of the rig; world_axis: the normal of the world
    mirror plane (a floor axis).  An involution; sign continuity over time is kept.
    """
    q = np.asarray(local_quats, np.float64)[..., np.asarray(twin, np.int64), :]
    out_q = _reflect_conj(q, rest_axis)
    root = _reflect_conj(q[..., 0, :], rest_axis)         # N G_0 N; then M G_0 N = (M N)(N G_0 N)
    if world_axis != rest_axis:                          # M N: half a turn about the third axis
        c = 3 - world_axis - rest_axis
        turn = np.zeros(4)
        turn[1 + c] = 1.0
        root = quat_mul(np.broadcast_to(turn, root.shape), root)
    out_q[..., 0, :] = root
    flip_w = np.ones(3)
    flip_w[world_axis] = -1.0
    out_r = np.asarray(root_pos, np.float64) * flip_w
    if local_pos is None:
        return out_q, out_r
    flip_n = np.ones(3)
    flip_n[rest_axis] = -1.0
    lp = np.asarray(local_pos, np.float64)[..., np.asarray(twin, np.int64), :] * flip_n
    lp[..., 0, :] = np.asarray(local_pos, np.float64)[..., 0, :] * flip_w
    return out_q, out_r, lp
