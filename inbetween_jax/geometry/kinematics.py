"""Forward and inverse kinematics over a parent array (pure ``jax.numpy``).

Like :mod:`quaternion`, every function computes in NumPy for NumPy inputs and in ``jax.numpy``
otherwise. Local positions follow the LaFAN1 convention: ``local_pos[..., 0, :]`` is the root's global
position and ``local_pos[..., j, :]`` for ``j > 0`` is joint ``j``'s offset in its parent's frame.
``parents`` is a static sequence of ints with ``parents[0] == -1`` and ``parents[j] < j``.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from inbetween_jax.geometry.quaternion import _xp, quat_inv, quat_mul, quat_rotate


def _check_parents(parents: Sequence[int], num_joints: int) -> tuple[int, ...]:
    parents = tuple(int(p) for p in parents)
    if len(parents) != num_joints:
        raise ValueError(f"parents has {len(parents)} entries but the arrays have {num_joints} joints")
    if parents[0] != -1 or any(not (0 <= p < j) for j, p in enumerate(parents) if j > 0):
        raise ValueError("parents must have parents[0] == -1 and 0 <= parents[j] < j")
    return parents


def depth_levels(parents: Sequence[int]) -> list[np.ndarray]:
    """Joint indices grouped by depth in the tree: ``[array([0]), children of 0, grandchildren, ...]``."""
    depth = [0] * len(parents)
    for j in range(1, len(parents)):
        depth[j] = depth[parents[j]] + 1
    return [np.flatnonzero(np.asarray(depth) == d) for d in range(max(depth) + 1)]


def forward_kinematics(local_quats, local_pos, parents: Sequence[int]):
    """Local rotations + local positions -> global rotations and positions.

    local_quats: (..., J, 4); local_pos: (..., J, 3) (broadcastable, e.g. offsets without batch dims).
    Returns ``(global_quats (..., J, 4), global_pos (..., J, 3))``.

    Joints are processed one depth level at a time (all joints of a level in one vectorised step), so
    the traced graph has one quaternion product per level (about 8 for a human skeleton) instead of one
    per joint, which keeps compile times of models that differentiate through FK short.
    """
    xp = _xp(local_quats, local_pos)
    parents = _check_parents(parents, local_quats.shape[-2])
    shape = xp.broadcast_shapes(local_quats.shape[:-1], local_pos.shape[:-1])
    local_pos = xp.broadcast_to(local_pos, shape + (3,))
    levels = depth_levels(parents)
    order = np.concatenate(levels)                  # joints in level order
    slot = np.empty(len(parents), np.int64)
    slot[order] = np.arange(len(parents))           # joint -> position in the level-ordered arrays
    gq, gp = [local_quats[..., :1, :]], [local_pos[..., :1, :]]
    for idx in levels[1:]:
        done_q = xp.concatenate(gq, axis=-2) if len(gq) > 1 else gq[0]
        done_p = xp.concatenate(gp, axis=-2) if len(gp) > 1 else gp[0]
        par = slot[np.asarray([parents[j] for j in idx])]
        pq, pp = done_q[..., par, :], done_p[..., par, :]
        gp.append(quat_rotate(pq, local_pos[..., idx, :]) + pp)
        gq.append(quat_mul(pq, local_quats[..., idx, :]))
    # gathering the level-ordered arrays at ``slot`` puts the joints back in their own order
    return xp.concatenate(gq, axis=-2)[..., slot, :], xp.concatenate(gp, axis=-2)[..., slot, :]


def inverse_kinematics(global_quats, global_pos, parents: Sequence[int]):
    """Global rotations and positions -> local rotations and local positions (inverse of FK).

    global_quats: (..., J, 4); global_pos: (..., J, 3). Returns ``(local_quats, local_pos)`` with the
    same shapes; ``local_pos[..., 0]`` is the root's global position.
    """
    xp = _xp(global_quats, global_pos)
    parents = _check_parents(parents, global_quats.shape[-2])
    par = np.asarray(parents[1:])
    parent_inv = quat_inv(global_quats[..., par, :])
    lq = xp.concatenate([global_quats[..., :1, :], quat_mul(parent_inv, global_quats[..., 1:, :])], axis=-2)
    lp = xp.concatenate(
        [global_pos[..., :1, :], quat_rotate(parent_inv, global_pos[..., 1:, :] - global_pos[..., par, :])],
        axis=-2)
    return lq, lp


def local_positions(root_pos, offsets):
    """Assemble local positions from a root trajectory and bone offsets.

    root_pos: (..., 3); offsets: (J, 3) (row 0 ignored). Returns (..., J, 3).
    """
    xp = _xp(root_pos, offsets)
    offs = xp.broadcast_to(offsets[1:], root_pos.shape[:-1] + offsets[1:].shape)
    return xp.concatenate([root_pos[..., None, :], offs], axis=-2)


def bone_lengths(global_pos, parents: Sequence[int]):
    """Distance of every non-root joint to its parent: (..., J, 3) -> (..., J-1)."""
    xp = _xp(global_pos)
    par = np.asarray(tuple(parents)[1:])
    return xp.linalg.norm(global_pos[..., 1:, :] - global_pos[..., par, :], axis=-1)
