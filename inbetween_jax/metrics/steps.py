"""Steps: does a fill walk, or do its feet glide with the body?  Counted as foot lift-offs.

A foot is in stance on a frame when its horizontal speed is below ``STANCE_FRACTION`` of the root's mean
horizontal speed over the motion (at least ``MIN_STANCE_SPEED``, so a body standing still has feet in stance).
A lift-off is a stance frame followed by a non-stance one.  Slerp between two walking keyframes moves every foot
with the body at about the root's speed: no stance, no lift-off.  Captured walking lifts each foot about once a
second.  Positions (..., T, J, 3), Y up, in cm; one value per leading index.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["STANCE_FRACTION", "MIN_STANCE_SPEED", "lift_offs"]

STANCE_FRACTION = 0.5
MIN_STANCE_SPEED = 0.5        # cm per frame


@jax.jit
def lift_offs(positions, foot_joints):
    """Lift-offs of the feet over the motion: positions (..., T, J, 3); foot_joints: the ankle joint of each
    foot (e.g. ``(left_ankle, right_ankle)``).  Returns (...,) float: the sum over the feet."""
    p = jnp.asarray(positions)
    root = jnp.linalg.norm(jnp.diff(p[..., :, 0, :][..., [0, 2]], axis=-2), axis=-1)          # (..., T-1)
    thresh = jnp.maximum(STANCE_FRACTION * jnp.mean(root, -1), MIN_STANCE_SPEED)               # (...,)
    feet = jnp.take(p, jnp.asarray(foot_joints, jnp.int32), axis=-2)[..., [0, 2]]              # (..., T, F, 2)
    speed = jnp.linalg.norm(jnp.diff(feet, axis=-3), axis=-1)                                  # (..., T-1, F)
    stance = speed < thresh[..., None, None]
    lifts = stance[..., :-1, :] & ~stance[..., 1:, :]
    return jnp.sum(lifts, axis=(-1, -2)).astype(jnp.float32)
