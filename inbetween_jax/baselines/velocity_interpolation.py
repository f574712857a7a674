"""Interpolation that continues the motion of the past frames: Slerp / lerp plus a cubic Hermite offset.

For protocols with more than one past frame (the official LaFAN1 benchmark gives 10).  At transition time t
(frames after the last past keyframe, L = frames between the keyframes) every channel gets

    offset(t) = v0 * t * (1 - t / L)^2,   v0 = (last past frame's velocity) - (the interpolation's velocity),

the cubic Hermite curve whose start tangent is the motion's and whose end tangent is the interpolation's: the
path leaves the keyframe with the motion's velocity and reaches the target exactly.  ``damping`` (per frame,
default 0) multiplies the offset by ``exp(-damping * t)``: the same start velocity, but the continued motion
fades within about ``1 / damping`` frames instead of carrying across long gaps (where the cubic overshoots).
Root: the displacement per frame; joints: the rotation vector of ``q_prev^-1 q`` in the joint's own frame,
applied as ``q_interp * exp(offset)``.  No parameters, nothing learned.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from inbetween_jax.baselines.interpolation import interpolate_transition
from inbetween_jax.geometry import quat_align, quat_conj, quat_from_axis_angle, quat_mul, quat_to_axis_angle

__all__ = ["hermite_weights", "end_hermite_weights", "rotation_vector", "rotation_from_vector", "velocity_offsets",
           "velocity_interpolate_transition"]


def hermite_weights(length, max_length: int, damping: float = 0.0):
    """(T1,) ``t * (1 - t / L)^2 * exp(-damping * t)`` at t = 0..max_length, zero from ``t = L`` on
    (``length`` = L)."""
    t = jnp.arange(max_length + 1, dtype=jnp.float32)
    s = jnp.clip(t / jnp.maximum(length, 1).astype(jnp.float32), 0.0, 1.0)
    return t * (1.0 - s) ** 2 * jnp.exp(-damping * t)


def rotation_vector(q):
    """(..., 4) unit quaternion -> (..., 3) axis * angle (:func:`~inbetween_jax.geometry.quat_to_axis_angle`)."""
    axis, angle = quat_to_axis_angle(q)
    return axis * angle[..., None]


def rotation_from_vector(v):
    """(..., 3) axis * angle -> (..., 4) unit quaternion (:func:`~inbetween_jax.geometry.quat_from_axis_angle`;
    a zero vector gives the identity)."""
    angle = jnp.sqrt(jnp.sum(v ** 2, -1))
    return quat_from_axis_angle(v / jnp.maximum(angle, 1e-12)[..., None], angle)


def end_hermite_weights(length, max_length: int, damping: float = 0.0):
    """(T1,) ``-t * (t / L) * (1 - t / L) * exp(-damping * (L - t))`` at t = 0..max_length (the end tangent's
    basis, zero at both keyframes and from ``t = L`` on)."""
    t = jnp.arange(max_length + 1, dtype=jnp.float32)
    n = jnp.maximum(length, 1).astype(jnp.float32)
    s = jnp.clip(t / n, 0.0, 1.0)
    return -t * s * (1.0 - s) * jnp.exp(-damping * jnp.maximum(n - t, 0.0))


def velocity_offsets(q_prev, q0, q1, r_prev, r0, r1, length, max_length: int, damping: float = 0.0,
                     q_next=None, r_next=None):
    """Apply-ready Hermite offsets at t = 0..max_length.

    q_prev / q0 / q1: (B, J, 4) local quaternions of the frame before the start keyframe, the start and the
    target keyframe (q1 sign-aligned to q0); r_*: (B, 3) root positions; q_next / r_next (optional): the frame
    after the target, for the two-sided form; q_prev = r_prev = None: no start term (the path leaves the start
    keyframe at the interpolation's velocity).  Returns (dq (B, T1, J, 4) to right-multiply onto the Slerp path,
    dr (B, T1, 3) to add to the lerp); damping: module docstring."""
    n = jnp.maximum(length, 1).astype(jnp.float32)
    w_interp = rotation_vector(quat_mul(quat_conj(q0), q1)) / n
    w = jnp.zeros(q0.shape[:1] + (max_length + 1,) + w_interp.shape[1:], jnp.float32)
    dr = jnp.zeros(r0.shape[:1] + (max_length + 1, 3), jnp.float32)
    if q_prev is not None:
        f = hermite_weights(length, max_length, damping)
        w = w + (rotation_vector(quat_mul(quat_conj(q_prev), q0)) - w_interp)[:, None] * f[None, :, None, None]
        dr = dr + ((r0 - r_prev) - (r1 - r0) / n)[:, None] * f[None, :, None]
    if q_next is not None:
        g = end_hermite_weights(length, max_length, damping)
        w = w + (rotation_vector(quat_mul(quat_conj(q1), q_next)) - w_interp)[:, None] * g[None, :, None, None]
        dr = dr + ((r_next - r1) - (r1 - r0) / n)[:, None] * g[None, :, None]
    return rotation_from_vector(w), dr


def velocity_interpolate_transition(local_quats, root_pos, n_past: int, n_trans: int, damping: float = 0.0,
                                    end_velocity: bool = False):
    """The transition frames ``n_past .. n_past + n_trans - 1`` between keyframes ``n_past - 1`` and
    ``n_past + n_trans``, continuing the motion of frame ``n_past - 2`` (needs ``n_past >= 2``); damping:
    module docstring.  end_velocity: also arrive with the motion of frame ``n_past + n_trans + 1`` (the two-sided
    form; needs that frame).

    local_quats: (B, T, J, 4); root_pos: (B, T, 3).  Returns (quats (B, n_trans, J, 4), root (B, n_trans, 3)),
    float64 numpy."""
    if n_past < 2:
        raise ValueError(f"n_past={n_past}: the velocity path needs at least two past frames")
    q = np.asarray(local_quats, np.float64)
    r = np.asarray(root_pos, np.float64)
    sl, lerp = interpolate_transition(q, r, n_past, n_trans)                     # the official interpolation
    k0, k1, length = n_past - 1, n_past + n_trans, n_trans + 1
    if end_velocity and q.shape[1] <= k1 + 1:
        raise ValueError(f"end_velocity: the clips have no frame after the target keyframe {k1}")
    q1 = quat_align(q[:, k1], q[:, k0])
    nxt = {}
    if end_velocity:
        nxt = {"q_next": jnp.asarray(quat_align(q[:, k1 + 1], q1), jnp.float32),
               "r_next": jnp.asarray(r[:, k1 + 1], jnp.float32)}
    dq, dr = velocity_offsets(*(jnp.asarray(x, jnp.float32) for x in (q[:, k0 - 1], q[:, k0], q1, r[:, k0 - 1],
                                                                      r[:, k0], r[:, k1])), length, length,
                                damping, **nxt)
    quats = quat_mul(np.asarray(sl, np.float64), np.asarray(dq[:, 1:length], np.float64))
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    return quats, np.asarray(lerp, np.float64) + np.asarray(dr[:, 1:length], np.float64)
