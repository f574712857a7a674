"""Quaternion math in pure ``jax.numpy``.

Convention: quaternions are ``(..., 4)`` arrays in (w, x, y, z) order, Hamilton product.
``quat_mul(a, b)`` is the rotation "b, then a": ``quat_rotate(quat_mul(a, b), v) ==
quat_rotate(a, quat_rotate(b, v))``. Every function broadcasts over leading dimensions and is
``jit`` / ``vmap`` / ``grad`` safe (no data-dependent Python control flow).

The functions are written against the array API shared by NumPy and ``jax.numpy``: given only NumPy
arrays they compute in NumPy (float64 data preparation, exact BVH round trips); given any JAX array
or tracer they compute in ``jax.numpy``.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

def _xp(*arrays):
    """``numpy`` if every argument is a NumPy array or scalar, else ``jax.numpy``."""
    return np if all(isinstance(a, (np.ndarray, np.generic, float, int)) for a in arrays) else jnp


_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def quat_identity(shape=(), dtype=jnp.float32):
    """Identity quaternions of shape ``shape + (4,)``."""
    return jnp.zeros(tuple(shape) + (4,), dtype).at[..., 0].set(1.0)


def quat_mul(a, b):
    """Hamilton product ``a * b``: (..., 4), (..., 4) -> (..., 4)."""
    xp = _xp(a, b)
    aw, ax, ay, az = xp.moveaxis(a, -1, 0)
    bw, bx, by, bz = xp.moveaxis(b, -1, 0)
    return xp.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def quat_conj(q):
    """Conjugate (the inverse of a unit quaternion): (..., 4) -> (..., 4)."""
    xp = _xp(q)
    return q * xp.asarray([1.0, -1.0, -1.0, -1.0], q.dtype)


def quat_inv(q):
    """Inverse of a unit quaternion (same as :func:`quat_conj`): (..., 4) -> (..., 4)."""
    xp = _xp(q)
    return quat_conj(q)


def quat_normalize(q, eps: float = 1e-8):
    """Scale to unit norm: (..., 4) -> (..., 4). Norms below ``eps`` are floored (zero stays finite)."""
    xp = _xp(q)
    return q / xp.sqrt(xp.maximum(xp.sum(q * q, axis=-1, keepdims=True), eps * eps))


def quat_rotate(q, v):
    """Rotate vectors by unit quaternions: (..., 4), (..., 3) -> (..., 3)."""
    xp = _xp(q, v)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * xp.cross(u, v)
    return v + w * t + xp.cross(u, t)


def quat_from_axis_angle(axis, angle):
    """Rotation of ``angle`` radians about unit ``axis``: (..., 3), (...) -> (..., 4)."""
    xp = _xp(axis, angle)
    half = 0.5 * angle[..., None]
    return xp.concatenate([xp.cos(half), xp.sin(half) * axis], axis=-1)


def quat_to_axis_angle(q, eps: float = 1e-8):
    """Inverse of :func:`quat_from_axis_angle`: (..., 4) -> axis (..., 3), angle (...) in [0, 2pi)."""
    xp = _xp(q)
    q = q * xp.where(q[..., :1] < 0, -1.0, 1.0)
    s = xp.sqrt(xp.sum(q[..., 1:] ** 2, axis=-1))
    angle = 2.0 * xp.arctan2(s, q[..., 0])
    axis = q[..., 1:] / xp.maximum(s, eps)[..., None]
    return axis, angle


def quat_from_euler(angles, order: str):
    """Quaternions from Euler angles in radians, BVH style.

    ``order`` is the channel order as written in a BVH file, e.g. ``"zyx"`` for
    ``Zrotation Yrotation Xrotation``: the rotation is ``R = R_order[0] @ R_order[1] @ R_order[2]``
    (intrinsic), with ``angles[..., i]`` the angle of axis ``order[i]``.

    angles: (..., 3) -> (..., 4)
    """
    xp = _xp(angles)
    order = order.lower()
    if len(order) != 3 or any(c not in _AXES for c in order):
        raise ValueError(f"Euler order must be three of 'xyz', got {order!r}")
    qs = [quat_from_axis_angle(xp.asarray(_AXES[c], angles.dtype), angles[..., i])
          for i, c in enumerate(order)]
    return quat_mul(qs[0], quat_mul(qs[1], qs[2]))


def quat_to_matrix(q):
    """Unit quaternions to rotation matrices: (..., 4) -> (..., 3, 3)."""
    xp = _xp(q)
    w, x, y, z = xp.moveaxis(q, -1, 0)
    return xp.stack([
        xp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        xp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        xp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def quat_from_matrix(m):
    """Rotation matrices to unit quaternions with w >= 0: (..., 3, 3) -> (..., 4).

    Uses the numerically stable branch selection (largest of w, x, y, z) computed for every branch
    and selected with ``where`` so it stays traceable.
    """
    xp = _xp(m)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    tr = m00 + m11 + m22
    cands = xp.stack([
        xp.stack([1 + tr, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                   m[..., 1, 0] - m[..., 0, 1]], -1),
        xp.stack([m[..., 2, 1] - m[..., 1, 2], 1 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0],
                   m[..., 0, 2] + m[..., 2, 0]], -1),
        xp.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 - m00 + m11 - m22,
                   m[..., 1, 2] + m[..., 2, 1]], -1),
        xp.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1],
                   1 - m00 - m11 + m22], -1),
    ], axis=-2)  # (..., 4 branches, 4)
    diag = xp.stack([tr, m00, m11, m22], -1)
    best = xp.argmax(diag, axis=-1)
    q = xp.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    q = quat_normalize(q)
    return q * xp.where(q[..., :1] < 0, -1.0, 1.0)


def quat_to_euler(q, order: str):
    """Unit quaternions to Euler angles (radians) in BVH channel ``order``: (..., 4) -> (..., 3).

    Inverse of :func:`quat_from_euler` (angles of the middle axis in [-pi/2, pi/2]). Works for all
    six Tait-Bryan orders by decomposing the rotation matrix.
    """
    xp = _xp(q)
    order = order.lower()
    if sorted(order) != ["x", "y", "z"]:
        raise ValueError(f"Euler order must be a permutation of 'xyz', got {order!r}")
    i, j, k = ("xyz".index(c) for c in order)
    r = quat_to_matrix(q)
    # R = R_i(a) R_j(b) R_k(c). The sign of the permutation fixes the signs below.
    sign = 1.0 if (j - i) % 3 == 1 else -1.0
    b = xp.arcsin(xp.clip(sign * r[..., i, k], -1.0, 1.0))
    a = xp.arctan2(-sign * r[..., j, k], r[..., k, k])
    c = xp.arctan2(-sign * r[..., i, j], r[..., i, i])
    return xp.stack([a, b, c], axis=-1)


def quat_between(u, v, eps: float = 1e-8):
    """Shortest-arc rotation taking direction ``u`` to direction ``v``: (..., 3), (..., 3) -> (..., 4).

    Same formula as the official LaFAN1 code (``[|u||v| + u.v, u x v]``, then normalised).
    """
    xp = _xp(u, v)
    w = xp.sqrt(xp.sum(u * u, -1) * xp.sum(v * v, -1)) + xp.sum(u * v, -1)
    return quat_normalize(xp.concatenate([w[..., None], xp.cross(u, v)], axis=-1), eps)


def quat_slerp(q0, q1, t, linear_threshold: float = 0.01):
    """Spherical linear interpolation along the shorter arc.

    q0, q1: (..., 4) unit quaternions; t: broadcastable to (...). Returns (..., 4), normalised.
    Falls back to linear blending when ``1 - |q0.q1| < linear_threshold`` (as the official LaFAN1
    benchmark does), which also keeps gradients finite.
    """
    xp = _xp(q0, q1, t)
    t = xp.asarray(t, q0.dtype)
    shape = xp.broadcast_shapes(q0.shape[:-1], q1.shape[:-1], t.shape)
    q0 = xp.broadcast_to(q0, shape + (4,))
    q1 = xp.broadcast_to(q1, shape + (4,))
    dot = xp.sum(q0 * q1, axis=-1)
    q1 = xp.where((dot < 0)[..., None], -q1, q1)
    dot = xp.abs(dot)
    linear = (1.0 - dot) < linear_threshold
    omega = xp.arccos(xp.clip(xp.where(linear, 0.0, dot), -1.0, 1.0))
    sin_om = xp.sin(omega)
    safe_sin = xp.where(linear, 1.0, sin_om)
    t = xp.broadcast_to(t, shape)
    w0 = xp.where(linear, 1.0 - t, xp.sin((1.0 - t) * omega) / safe_sin)
    w1 = xp.where(linear, t, xp.sin(t * omega) / safe_sin)
    return quat_normalize(w0[..., None] * q0 + w1[..., None] * q1)


def quat_align(q, ref):
    """Flip quaternions q (..., 4) into the hemisphere of ref (broadcast against q): the same rotations."""
    xp = _xp(q, ref)
    return xp.where(xp.sum(q * ref, axis=-1, keepdims=True) < 0, -q, q)


def quat_fix_sign(q, axis: int = 0):
    """Sign continuity: flip each quaternion so it lies in the hemisphere of its predecessor.

    q: (..., 4) with time along ``axis`` (counted among the leading dims). Returns the same shape.
    Sequential by nature; implemented with a cumulative product of flips so it is traceable.
    """
    xp = _xp(q, axis)
    q = xp.moveaxis(q, axis, 0)
    dots = xp.sum(q[1:] * q[:-1], axis=-1)
    flips = xp.where(dots < 0, -1.0, 1.0).astype(q.dtype)
    signs = xp.concatenate([xp.ones_like(flips[:1]), xp.cumprod(flips, axis=0)], axis=0)
    return xp.moveaxis(q * signs[..., None], 0, axis)


def quat_fix_sign_np(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """NumPy twin of :func:`quat_fix_sign` for data preparation (float64 stays float64)."""
    q = np.moveaxis(np.array(q, copy=True), axis, 0)
    for t in range(1, q.shape[0]):
        flip = np.sum(q[t] * q[t - 1], axis=-1) < 0
        q[t][flip] *= -1
    return np.moveaxis(q, 0, axis)


def quat_to_forward_up(q):
    """Rotation as the rotated forward (+Z) and up (+Y) axes, a continuous 6-d representation.

    (..., 4) -> (..., 6) = [forward xyz, up xyz].
    """
    xp = _xp(q)
    fwd = quat_rotate(q, xp.broadcast_to(xp.asarray([0.0, 0.0, 1.0], q.dtype), q.shape[:-1] + (3,)))
    up = quat_rotate(q, xp.broadcast_to(xp.asarray([0.0, 1.0, 0.0], q.dtype), q.shape[:-1] + (3,)))
    return xp.concatenate([fwd, up], axis=-1)


def quat_from_forward_up(fu, eps: float = 1e-8):
    """Inverse of :func:`quat_to_forward_up` with Gram-Schmidt: (..., 6) -> (..., 4)."""
    xp = _xp(fu)
    z = fu[..., :3] / (xp.linalg.norm(fu[..., :3], axis=-1, keepdims=True) + eps)
    y = fu[..., 3:] - xp.sum(fu[..., 3:] * z, -1, keepdims=True) * z
    y = y / (xp.linalg.norm(y, axis=-1, keepdims=True) + eps)
    x = xp.cross(y, z)
    return quat_from_matrix(xp.stack([x, y, z], axis=-1))
