"""Positions -> rotations: fit BVH joint rotations to target joint positions (swing-only, twist kept)."""
from __future__ import annotations

import numpy as np

from inbetween_jax.geometry.quaternion import quat_between, quat_inv, quat_mul, quat_normalize, quat_rotate

__all__ = ["fit_rotations", "main_child"]


def main_child(parents, j):
    kids = [c for c, p in enumerate(parents) if p == j]
    if not kids:
        return None
    # the child with the largest subtree (e.g. the spine for the hips)
    def size(c):
        return 1 + sum(size(k) for k, p in enumerate(parents) if p == c)
    return max(kids, key=size)


def fit_rotations(global_pos, ref_quats, local_pos, parents, frames) -> tuple:
    """Positions -> BVH rotations on the selected frames (a simple swing-only fit, documented).

    global_pos: (T, J, 3) target positions; ref_quats: (T, J, 4) initial local rotations (e.g. the input's,
    slerped across gaps); local_pos: (T, J, 3) the skeleton's offsets (row 0 replaced by the root position);
    frames: (T,) bool.  On the selected frames the root position is the target root and, joint by joint
    from the root, the global rotation is corrected by the shortest-arc rotation that points the bone to
    its main child (largest subtree) at the target position; twist comes from ``ref_quats``.
    Returns ``(local_quats (T, J, 4), local_pos (T, J, 3))``.
    """
    gp = np.asarray(global_pos, np.float64)
    lq = np.array(ref_quats, np.float64, copy=True)
    lp = np.array(local_pos, np.float64, copy=True)
    sel = np.asarray(frames, bool)
    if not sel.any():
        return lq, lp
    lp[sel, 0] = gp[sel, 0]
    q, tgt, offs = lq[sel], gp[sel], lp[sel]
    glob = [None] * len(parents)
    for j in range(len(parents)):
        p = parents[j]
        g = q[:, j] if p < 0 else quat_mul(glob[p], q[:, j])
        c = main_child(parents, j)
        if c is not None:
            cur = quat_rotate(g, np.broadcast_to(offs[:, c], g.shape[:-1] + (3,)))
            want = tgt[:, c] - tgt[:, j]
            ok = (np.linalg.norm(cur, axis=-1) > 1e-6) & (np.linalg.norm(want, axis=-1) > 1e-6)
            corr = quat_between(np.where(ok[:, None], cur, [1.0, 0, 0]), np.where(ok[:, None], want, [1.0, 0, 0]))
            g = quat_normalize(quat_mul(corr, g))
            q[:, j] = g if p < 0 else quat_normalize(quat_mul(quat_inv(glob[p]), g))
        glob[j] = g
    lq[sel] = q
    return lq, lp
