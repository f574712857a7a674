"""Foot metrics: contact-masked foot sliding (S-CVAE style) and height-weighted foot skating
(two-character interaction paper; the weighting of Zhang et al. 2018).

Positions are global ``(..., T, J, 3)``, Y up (``up_axis=1``), floor at ``floor_height``; the
"horizontal" plane is the two other axes (XZ). ``foot_joints`` is a sequence of F joint indices,
typically ``(left_ankle, left_toe, right_ankle, right_toe)`` (a stance foot = its ankle + toe).
Per-frame quantities live on the T-1 transitions ``t-1 -> t`` (t = 1..T-1); include the last
context frame before the gap if the displacement into the first generated frame should count.
All functions are pure ``jax.numpy`` and ``jit``-able (``foot_joints`` may be a tuple or an array).
"""
from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

__all__ = ["foot_heights", "horizontal_displacement", "foot_sliding_frames", "foot_sliding",
           "foot_skating_weight", "foot_skating_frames", "foot_skating"]

SKATING_HEIGHT_CM = 2.5


def _feet(positions, foot_joints):
    positions = jnp.asarray(positions)
    return jnp.take(positions, jnp.asarray(foot_joints, jnp.int32), axis=-2)  # (..., T, F, 3)


def _horizontal(x, up_axis: int):
    keep = [a for a in range(3) if a != up_axis % 3]
    return x[..., keep]


@functools.partial(jax.jit, static_argnames=('up_axis',))
def foot_heights(positions, foot_joints, up_axis: int = 1, floor_height: float = 0.0):
    """Height above the floor ``h[..., t, f] = p[..., t, foot_joints[f], up_axis] - floor_height``.

    positions: (..., T, J, 3). Returns (..., T, F) in input units.
    """
    return _feet(positions, foot_joints)[..., up_axis] - floor_height


@functools.partial(jax.jit, static_argnames=('up_axis',))
def horizontal_displacement(positions, foot_joints, up_axis: int = 1):
    """Horizontal displacement of each foot joint between consecutive frames,

        d[..., t-1, f] = || hor(p[..., t, foot_f]) - hor(p[..., t-1, foot_f]) ||_2,   t = 1..T-1

    with hor() dropping the up axis. positions: (..., T, J, 3). Returns (..., T-1, F), input units.
    """
    feet = _horizontal(_feet(positions, foot_joints), up_axis)
    sq = jnp.sum((feet[..., 1:, :, :] - feet[..., :-1, :, :]) ** 2, axis=-1)
    return jnp.sqrt(jnp.where(sq > 0, sq, 0.0))


@functools.partial(jax.jit, static_argnames=('up_axis',))
def foot_sliding_frames(positions, foot_joints, contacts=None, height_threshold=5.0,
                        velocity_threshold=None, up_axis: int = 1, floor_height: float = 0.0):
    """S-CVAE style foot sliding on each transition ``t-1 -> t``:

        slide[..., t-1, f] = c[..., t-1, f] * c[..., t, f] * d[..., t-1, f]

    where d is :func:`horizontal_displacement` (a foot in stance should not move horizontally) and
    c in [0, 1] is the contact (stance) label of foot joint f, the ankle and toe joints being labelled
    separately. Contacts come from
      * ``contacts`` (..., T, F) if given -- recommended: the ground-truth labels of the dataset
        (``data.features.foot_contacts``), so the prediction is judged where the real foot is planted;
      * otherwise a height rule on ``positions``: ``c = h < height_threshold`` (scalar or (F,) per foot
        joint, input units; the default 5.0 assumes cm and a toe-like joint, pass larger thresholds
        for ankles), and if ``velocity_threshold`` is not None additionally the 3D speed rule
        ``||p[t] - p[t-1]|| < velocity_threshold`` on that transition; a transition then counts
        (weight 1) when the height test holds at both frames AND the speed test holds, else 0.

    positions: (..., T, J, 3). Returns (..., T-1, F) in input units per frame.
    """
    disp = horizontal_displacement(positions, foot_joints, up_axis)
    if contacts is not None:
        c = jnp.asarray(contacts, disp.dtype)
        weight = c[..., :-1, :] * c[..., 1:, :]
    else:
        h = foot_heights(positions, foot_joints, up_axis, floor_height)
        low = h < jnp.asarray(height_threshold, disp.dtype)
        weight = low[..., :-1, :] & low[..., 1:, :]
        if velocity_threshold is not None:
            feet = _feet(positions, foot_joints)
            speed = jnp.sqrt(jnp.sum((feet[..., 1:, :, :] - feet[..., :-1, :, :]) ** 2, axis=-1))
            weight = weight & (speed < velocity_threshold)
        weight = weight.astype(disp.dtype)
    return weight * disp


@functools.partial(jax.jit, static_argnames=('up_axis',))
def foot_sliding(positions, foot_joints, contacts=None, height_threshold=5.0,
                 velocity_threshold=None, up_axis: int = 1, floor_height: float = 0.0,
                 scale: float = 1.0):
    """Foot sliding per frame: ``scale * mean over (batch, T-1 transitions, F foot joints)`` of
    :func:`foot_sliding_frames` (non-contact entries count as 0).

    positions: (..., T, J, 3); contacts: optional (..., T, F). Returns a scalar in input units per
    frame times ``scale`` (cm/frame for LaFAN1 / CMU data).
    """
    return scale * jnp.mean(foot_sliding_frames(positions, foot_joints, contacts, height_threshold,
                                                velocity_threshold, up_axis, floor_height))


@jax.jit
def foot_skating_weight(h, H: float = SKATING_HEIGHT_CM):
    """Skating weight ``w(h) = clamp(2 - 2^(h / H), 0, 1)``: 1 on / below the floor, 2 - sqrt(2) at
    h = H/2, 0 for h >= H. h: any shape, same units as H (default 2.5 cm). Returns h's shape."""
    h = jnp.asarray(h)
    return jnp.clip(2.0 - jnp.exp2(h / H), 0.0, 1.0)


@functools.partial(jax.jit, static_argnames=('up_axis',))
def foot_skating_frames(positions, foot_joints, H: float = SKATING_HEIGHT_CM, up_axis: int = 1,
                        floor_height: float = 0.0):
    """Interaction-paper foot skating on each transition ``t-1 -> t``:

        s[..., t-1, f] = d[..., t-1, f] * clamp(2 - 2^(h[..., t, f] / H), 0, 1)

    with d the horizontal displacement (:func:`horizontal_displacement`) and h the height above the
    floor of foot joint f at the current frame t. positions: (..., T, J, 3); H in input units
    (2.5 cm). Returns (..., T-1, F) in input units per frame.
    """
    disp = horizontal_displacement(positions, foot_joints, up_axis)
    h = foot_heights(positions, foot_joints, up_axis, floor_height)[..., 1:, :]
    return disp * foot_skating_weight(h, H)


@functools.partial(jax.jit, static_argnames=('up_axis',))
def foot_skating(positions, foot_joints, H: float = SKATING_HEIGHT_CM, up_axis: int = 1,
                 floor_height: float = 0.0, scale: float = 1.0):
    """Foot skating: ``scale * mean over (batch, T-1 transitions, F foot joints)`` of
    :func:`foot_skating_frames`. positions: (..., T, J, 3). Returns a scalar in input units per
    frame times ``scale`` (cm/frame for cm data)."""
    return scale * jnp.mean(foot_skating_frames(positions, foot_joints, H, up_axis, floor_height))
