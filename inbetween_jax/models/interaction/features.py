"""The representation of the interaction model: per-character joint features and rigid keypose spaces.

Per character and frame: J joints x 9 channels = global position (3) + global rotation as forward / up
vectors (6, :func:`~inbetween_jax.geometry.quat_to_forward_up`).  Feature arrays are ``(..., T, J, 9)``.

Rigid "spaces" are yaw rotations about +Y plus a translation, stored as ``(R, t)`` with ``R`` (..., 3, 3)
and ``t`` (..., 3); :func:`apply_space` maps space coordinates to the parent frame (``R x + t``) and
:func:`to_space` is its inverse.  A keyframe space has its origin at the keyframe root's floor projection
and its +Z axis along the keyframe character's facing direction.  Every function works on NumPy arrays
(NumPy out) and on JAX arrays / tracers.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.geometry import forward_kinematics, quat_to_forward_up
from inbetween_jax.geometry.heading import heading_angle, yaw_matrix

__all__ = ["LAFAN_FORWARD", "world_joint_features", "skeleton_forward_axis", "apply_space", "to_space",
           "compose_spaces", "relative_space", "facing_yaw", "root_space", "to_common_space", "mirror_feats",
           "skeleton_side_axis", "keyframe_sample", "scale_positions", "key_space_inputs"]

LAFAN_FORWARD = (0.0, 1.0, 0.0)


def _xp(x):
    import jax.numpy as jnp
    return np if isinstance(x, np.ndarray) else jnp


# ----------------------------------------------------------------------------- motion -> features
def world_joint_features(motion) -> np.ndarray:
    """World features of a :class:`Motion`: (T, J, 9) float64 (FK positions + forward/up)."""
    gq, gp = forward_kinematics(motion.local_quats, motion.local_pos, motion.skeleton.parents)
    return np.concatenate([gp, quat_to_forward_up(gq)], axis=-1)


def skeleton_forward_axis(skel: Skeleton) -> np.ndarray:
    """The root's local facing axis (3,): LaFAN1's +Y for its naming, else :meth:`Skeleton.forward_axis`."""
    if skel.names and skel.names[0] == "Hips" and "LeftToe" in skel.names:  # LaFAN1 naming
        return np.asarray(LAFAN_FORWARD)
    return np.asarray(skel.forward_axis(), np.float64)


# ----------------------------------------------------------------------------- rigid spaces
def apply_space(feat, R, t):
    """Space -> parent coordinates: positions ``R p + t``, forward/up ``R v``.

    feat (..., J, 9); R (..., 3, 3) and t (..., 3) broadcast against feat's leading dims (without J).
    """
    xp = _xp(feat)
    R = R[..., None, :, :]
    v = feat.reshape(feat.shape[:-1] + (3, 3))                # (..., J, 3 vectors, 3)
    out = xp.einsum("...ij,...kj->...ki", R, v)
    out = out + xp.stack([t, xp.zeros_like(t), xp.zeros_like(t)], -2)[..., None, :, :]
    return out.reshape(feat.shape)


def to_space(feat, R, t):
    """Inverse of :func:`apply_space`: parent -> space coordinates. Same shapes."""
    xp = _xp(feat)
    Rt = xp.swapaxes(R, -1, -2)
    return apply_space(feat, Rt, -xp.einsum("...ij,...j->...i", Rt, t))


def compose_spaces(Ra, ta, Rb, tb):
    """``(Rb, tb)``-space -> ``(Ra, ta)``'s parent, when ``(Rb, tb)`` is expressed in space a: R (..,3,3), t (..,3)."""
    xp = _xp(Ra)
    return Ra @ Rb, xp.einsum("...ij,...j->...i", Ra, tb) + ta


def relative_space(Ra, ta, Rb, tb):
    """The map from space a to space b (both given in one parent frame): ``x_b = R x_a + t``."""
    xp = _xp(Ra)
    Rbt = xp.swapaxes(Rb, -1, -2)
    return Rbt @ Ra, xp.einsum("...ij,...j->...i", Rbt, ta - tb)


def facing_yaw(root_feat, forward_axis):
    """Heading angle of a character from its root features: (..., 9) -> (...) radians (0 = facing +Z).

    The root's local ``forward_axis`` (3,) is rotated by the root rotation rebuilt from forward/up.
    """
    xp = _xp(root_feat)
    z = root_feat[..., 3:6]
    z = z / (xp.linalg.norm(z, axis=-1, keepdims=True) + 1e-8)
    y = root_feat[..., 6:9] - xp.sum(root_feat[..., 6:9] * z, -1, keepdims=True) * z
    y = y / (xp.linalg.norm(y, axis=-1, keepdims=True) + 1e-8)
    x = xp.cross(y, z)
    fa = xp.asarray(forward_axis, root_feat.dtype)
    return heading_angle(x * fa[0] + y * fa[1] + z * fa[2])


def root_space(root_feat, forward_axis):
    """Floor-projected root space ``(R, t)`` of root features (..., 9): R (..., 3, 3), t (..., 3)."""
    xp = _xp(root_feat)
    R = yaw_matrix(facing_yaw(root_feat, forward_axis))
    t = root_feat[..., :3] * xp.asarray([1.0, 0.0, 1.0], root_feat.dtype)
    return R, t


def to_common_space(feats, rel_R, rel_t):
    """Character B's features into character A's keyframe space: (B, 2, T, J, 9) -> same.

    rel_R (B, 2, 3, 3), rel_t (B, 2, 3): the maps from each character's key space to the other's.
    """
    xp = _xp(feats)
    b = apply_space(feats[:, 1], rel_R[:, 1, None], rel_t[:, 1, None])
    return xp.stack([feats[:, 0], b], 1)


# ----------------------------------------------------------------------------- samples
def mirror_feats(feat: np.ndarray, mirror_map: Sequence[int], rest_axis: int = 0) -> np.ndarray:
    """Mirror across the YZ plane (x -> -x) and swap left/right joints: (..., J, 9) -> (..., J, 9).

    rest_axis: the rig's left-right axis at rest (:func:`skeleton_side_axis`; 0 for CMU's rig, 2 for LaFAN1's).
    A mirrored joint's rotation is ``M G_twin N`` (``N`` the reflection across that axis,
    :mod:`inbetween_jax.geometry.mirror`), so its forward (+Z) / up (+Y) vector also flips sign when the rest
    axis is that local axis."""
    sign = np.tile(np.array([-1.0, 1.0, 1.0], feat.dtype), 3)
    if rest_axis == 2:                      # local +Z, the forward vector (channels 3-5)
        sign[3:6] *= -1.0
    elif rest_axis == 1:                    # local +Y, the up vector (channels 6-8)
        sign[6:9] *= -1.0
    return (feat * sign)[..., list(mirror_map), :]


def skeleton_side_axis(skel: Skeleton) -> int:
    """The rig's left-right axis at rest (:func:`~inbetween_jax.geometry.mirror.rest_side_axis`); 0 for a rig
    without left/right joints or without a symmetric rest pose (mirroring is then x -> -x alone)."""
    from inbetween_jax.geometry.mirror import rest_side_axis
    try:
        return rest_side_axis(skel.offsets, skel.mirror_map())
    except ValueError:
        return 0


def keyframe_sample(feats: np.ndarray, start: int, length: int, key: int, forward_axis) -> dict:
    """One sample: ``length`` frames from ``start`` and a keyframe at ``start + key``, each character in its
    own keyframe space.  feats (2, T, J, 9) world.

    Returns dict: ``x`` (2, length, J, 9), ``keypose`` (2, J, 9), ``rel_R`` (2, 3, 3), ``rel_t`` (2, 3)
    (map from character c's key space to the other's), ``world_R`` / ``world_t`` (2, 3, 3) / (2, 3)
    (key space -> world).
    """
    R, t = root_space(feats[:, start + key, 0], forward_axis)            # (2, 3, 3), (2, 3)
    x = to_space(feats[:, start:start + length], R[:, None], t[:, None])
    kp = to_space(feats[:, start + key], R, t)
    rel_R, rel_t = relative_space(R, t, R[::-1], t[::-1])
    return dict(x=x, keypose=kp, rel_R=rel_R, rel_t=rel_t, world_R=R, world_t=t)


def scale_positions(b: dict, s: float) -> dict:
    """Multiply the position channels (and translations) of a sample dict by ``s``."""
    b = dict(b)
    sc = np.array([s] * 3 + [1.0] * 6, np.float32)
    for k in ("x", "keypose"):
        b[k] = b[k] * sc
    for k in ("rel_t", "world_t"):
        b[k] = b[k] * np.float32(s)
    return b


def key_space_inputs(context, keyframes, forward_axis, pos_scale: float) -> dict:
    """Users' frames -> a one-sample network input, as :func:`keyframe_sample` builds training samples.

    context (2, n_input, J, 9) and keyframes (2, J, 9) world features -> dict of float32 arrays with a batch
    axis of 1: ``x``, ``keypose``, ``rel_R``, ``rel_t``, ``world_R`` (1, 2, 3, 3), ``world_t`` (1, 2, 3)
    (positions scaled by ``pos_scale``).
    """
    R, t = root_space(keyframes[:, 0], forward_axis)                      # (2, 3, 3), (2, 3)
    rel_R, rel_t = relative_space(R, t, R[::-1], t[::-1])
    b = {"x": to_space(context, R[:, None], t[:, None])[None], "keypose": to_space(keyframes, R, t)[None],
         "rel_R": rel_R[None], "rel_t": rel_t[None], "world_R": R[None], "world_t": t[None]}
    return {k: v.astype(np.float32) for k, v in scale_positions(b, pos_scale).items()}
