"""Heading (yaw about +Y) in one place: angles from directions, rotations about the up axis.

Convention (Y up, floor XZ): yaw 0 faces +Z and ``yaw = atan2(fx, fz)`` for a forward direction ``f``; a
rotation by ``yaw`` about +Y sends +Z to ``(sin yaw, 0, cos yaw)``.  Every function works on NumPy (float64 in,
float64 out) and on JAX arrays / tracers.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["heading_angle", "yaw_matrix", "rotate_about_up", "yaw_quat"]


def _xp(*xs):
    return jnp if any(isinstance(x, jax.Array) for x in xs) else np


def heading_angle(direction):
    """Yaw of direction vectors: (..., 3) (x, y, z) or (..., 2) (x, z) -> (...) radians, 0 = facing +Z."""
    xp = _xp(direction)
    x = direction[..., 0]
    z = direction[..., 2] if direction.shape[-1] == 3 else direction[..., 1]
    return xp.arctan2(x, z)


def yaw_matrix(yaw):
    """Rotation about +Y by ``yaw`` (radians), sending +Z to (sin yaw, 0, cos yaw): (...) -> (..., 3, 3)."""
    xp = _xp(yaw)
    c, s = xp.cos(yaw), xp.sin(yaw)
    z, o = xp.zeros_like(yaw), xp.ones_like(yaw)
    return xp.stack([xp.stack([c, z, s], -1), xp.stack([z, o, z], -1), xp.stack([-s, z, c], -1)], -2)


def rotate_about_up(xz, yaw):
    """Rotate floor-plane vectors (x, z) about +Y by ``yaw`` (as :func:`yaw_matrix`): xz (..., 2), yaw (...)
    -> (..., 2).  ``rotate_about_up((0, 1), a) == (sin a, cos a)``; ``-yaw`` maps into the heading's frame.
    """
    xp = _xp(xz, yaw)
    c, s = xp.cos(yaw), xp.sin(yaw)
    x, z = xz[..., 0], xz[..., 1]
    return xp.stack([x * c + z * s, -x * s + z * c], axis=-1)


def yaw_quat(q):
    """Heading-only part of rotations (about +Y), from where they send the +Z axis: (..., 4) -> (..., 4)."""
    from inbetween_jax.geometry.quaternion import quat_from_axis_angle, quat_rotate
    xp = _xp(q)
    fwd = quat_rotate(q, xp.broadcast_to(xp.asarray([0.0, 0.0, 1.0], q.dtype), q.shape[:-1] + (3,)))
    up = xp.broadcast_to(xp.asarray([0.0, 1.0, 0.0], q.dtype), q.shape[:-1] + (3,))
    return quat_from_axis_angle(up, heading_angle(fwd))
