"""The path the residual decoder (``model.residual``) adds its offsets to, at times 0..max_length.

* :func:`interpolation_path` -- Slerp of the local quaternions and lerp of the root between the keyframes (the
  official interpolation baseline): an untrained residual model reproduces it exactly.
* with ``model.base_velocity`` and a start keyframe that carries its previous frame (``qp``, ``v``): the same
  path plus the cubic Hermite offset of :mod:`inbetween_jax.baselines.velocity_interpolation`, which continues
  the start's velocity (root and every joint) and fades out by the target.  Only protocols with more than one past
  frame provide ``qp`` (the official LaFAN1 protocol); with one keyframe the path is the plain interpolation.
"""
from __future__ import annotations

import jax.numpy as jnp

from inbetween_jax.baselines.velocity_interpolation import velocity_offsets
from inbetween_jax.geometry import quat_mul, quat_slerp
from inbetween_jax.geometry.quaternion import quat_align

__all__ = ["interpolation_path", "base_path"]


def interpolation_path(start: dict, target: dict, length, max_length: int):
    """Slerp of local quaternions and lerp of the root between the keyframes at times 0..max_length
    (times >= length hold the target).  Returns q (B, T1, J, 4), r (B, T1, 3), T1 = max_length + 1."""
    w = jnp.clip(jnp.arange(max_length + 1, dtype=jnp.float32) / jnp.maximum(length, 1).astype(jnp.float32), 0, 1)
    q = quat_slerp(start["q"][:, None], quat_align(target["q"], start["q"])[:, None], w[None, :, None])
    r = start["r"][:, None] + w[None, :, None] * (target["r"] - start["r"])[:, None]
    return q, r


def base_path(start: dict, target: dict, length, max_length: int, velocity: bool = False, damping: float = 0.0):
    """The residual decoder's base at times 0..max_length: ``(q (B, T1, J, 4), r (B, T1, 3))``.

    start: ``q`` (B, J, 4), ``r`` (B, 3) and, for the velocity path, ``qp`` (B, J, 4) the previous frame's local
    quaternions and ``v`` (B, 3) the root's displacement from the previous frame.  velocity: add the Hermite
    offset (module docstring; ``damping`` per frame, ``model.base_damping``) when ``start`` carries ``qp`` and
    ``v``; otherwise the plain interpolation.  A start keyframe that carries ``base_q`` (B, T1, J, 4) and
    ``base_r`` (B, T1, 3) gives the path itself (``model.bank_base``)."""
    if "base_q" in start:
        return start["base_q"], start["base_r"]
    q, r = interpolation_path(start, target, length, max_length)
    if not (velocity and "qp" in start and "v" in start):
        return q, r
    dq, dr = velocity_offsets(start["qp"], start["q"], quat_align(target["q"], start["q"]), start["r"] - start["v"],
                              start["r"], target["r"], length, max_length, damping)
    return quat_mul(q, dq), r + dr
