"""Data side of the convolutional inpainting AE: the paper's representation (Sec. 3.1), clip banks,
training masks and the gap-length curriculum (Sec. 3.3).

Representation.  A frame is ``D = 3J + 3`` numbers: the J joints' 3D positions in the character's body
frame (origin at the root joint projected on the floor, Y up, rotated so that the character faces +Z;
joint order as the skeleton, x y z per joint), then the root's floor-plane velocity ``(vx, vz)`` and its
yaw velocity ``w`` (radians).  Velocities are relative to the previous frame and expressed in its body
frame: ``v_t = R(-yaw_{t-1}) (r_t - r_{t-1})``, ``w_t = wrap(yaw_t - yaw_{t-1})``; frame 0 copies frame 1.
The facing (yaw) is Holden et al.'s: the normal of the hips' and shoulders' left-right axis in the floor
plane, Gaussian-smoothed over time (:func:`facing_yaw`).  With 22 joints (LaFAN1) D = 69, as the paper's data.
A clip is an image ``(D, T)`` -- rows are features, columns frames -- normalised per row with training
statistics.  Host-side preparation is NumPy; masks and the curriculum are pure jnp with explicit keys.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.data.features import Normalizer
from inbetween_jax.geometry import forward_kinematics

__all__ = ["MotionFeatures", "motion_features", "features_to_global", "integrate_root", "yaw_rotate",
           "ClipBank", "build_clip_bank", "curriculum_mu", "gap_mask", "joint_row_mask", "training_mask",
           "frames_to_rows_mask", "split_features", "num_features"]


def num_features(num_joints: int) -> int:
    """D = 3J + 3."""
    return 3 * int(num_joints) + 3


def yaw_rotate(xz, yaw):
    """Rotate floor-plane vectors about +Y by ``yaw``: xz (..., 2), yaw (...) -> (..., 2).

    ``yaw_rotate((0, 1), a) == (sin a, cos a)`` (yaw 0 faces +Z).
    """
    xp = jnp if isinstance(xz, jax.Array) or isinstance(yaw, jax.Array) else np
    c, s = xp.cos(yaw), xp.sin(yaw)
    x, z = xz[..., 0], xz[..., 1]
    return xp.stack([x * c + z * s, -x * s + z * c], axis=-1)


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@dataclasses.dataclass
class MotionFeatures:
    """One motion in the CAE representation.

    features: (T, D) float32 (un-normalised); ref0: (2,) root floor position (x, z) at frame 0;
    yaw0: root yaw at frame 0 (radians); global_pos: (T, J, 3) float32 FK positions (cm);
    root_y: (T,) root height; name: source file.
    """

    features: np.ndarray
    ref0: np.ndarray
    yaw0: float
    global_pos: np.ndarray
    name: str = ""


def _side_joints(skeleton) -> list:
    """[(left, right)] index pairs used for the facing: the hips' leg children and, if found, the shoulders."""
    def top_child(j):
        while skeleton.parents[j] > 0:
            j = skeleton.parents[j]
        return j

    la, _, ra, _ = skeleton.foot_joints()
    pairs = [(top_child(la), top_child(ra))]
    names = [n.lower() for n in skeleton.names]
    for word in ("shoulder", "shldr", "clavicle", "collar", "arm"):
        left = [i for i, n in enumerate(names) if word in n and n.startswith(("left", "l"))
                and "fore" not in n and "up" not in n]
        right = [i for i, n in enumerate(names) if word in n and n.startswith(("right", "r"))
                 and "fore" not in n and "up" not in n]
        if left and right:
            pairs.append((left[0], right[0]))
            break
    return pairs


def facing_yaw(global_pos: np.ndarray, skeleton, smooth: float = 4.0) -> np.ndarray:
    """(T, J, 3) global positions -> (T,) facing yaw (``atan2(fx, fz)``, yaw 0 faces +Z).

    As Holden et al.: across = sum of (left - right) over the hip joints and the shoulders, forward =
    across x up, Gaussian-smoothed over time (``smooth`` frames std) before the angle is taken.
    """
    gp = np.asarray(global_pos, np.float64)
    across = sum(gp[:, a] - gp[:, b] for a, b in _side_joints(skeleton))
    fwd = np.stack([-across[:, 2], across[:, 0]], axis=-1)            # (fx, fz) = across x (0, 1, 0)
    if smooth > 0 and len(fwd) > 1:
        r = int(3 * smooth)
        k = np.exp(-0.5 * (np.arange(-r, r + 1) / smooth) ** 2)
        k /= k.sum()
        pad = np.pad(fwd, ((r, r), (0, 0)), mode="edge")
        fwd = np.stack([np.convolve(pad[:, i], k, mode="valid") for i in range(2)], axis=-1)
    return np.arctan2(fwd[:, 0], fwd[:, 1])


def positions_to_features(global_pos: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(T, J, 3) global positions + (T,) yaw -> (T, 3J + 3) features (see module docstring). T >= 2."""
    gp = np.asarray(global_pos, np.float64)
    t, j, _ = gp.shape
    ref = gp[:, 0, [0, 2]]                                         # (T, 2) root floor projection
    rel = gp.copy()
    rel[..., 0] -= ref[:, None, 0]
    rel[..., 2] -= ref[:, None, 1]
    loc_xz = yaw_rotate(rel[..., [0, 2]], -yaw[:, None])
    local = np.stack([loc_xz[..., 0], rel[..., 1], loc_xz[..., 1]], axis=-1)  # (T, J, 3)
    vel = np.zeros((t, 3))
    if t > 1:
        vel[1:, :2] = yaw_rotate(ref[1:] - ref[:-1], -yaw[:-1])
        vel[1:, 2] = _wrap(yaw[1:] - yaw[:-1])
        vel[0] = vel[1]
    return np.concatenate([local.reshape(t, 3 * j), vel], axis=1).astype(np.float32)


def motion_features(motion, smooth: float = 4.0) -> MotionFeatures:
    """A :class:`~inbetween_jax.data.Motion` -> :class:`MotionFeatures` (FK through the shared geometry)."""
    _, gp = forward_kinematics(np.asarray(motion.local_quats, np.float64), np.asarray(motion.local_pos, np.float64),
                               motion.skeleton.parents)
    yaw = facing_yaw(gp, motion.skeleton, smooth)
    feats = positions_to_features(gp, yaw)
    return MotionFeatures(feats, gp[0, 0, [0, 2]].astype(np.float64), float(yaw[0]), gp.astype(np.float32),
                          getattr(motion, "source", ""))


def split_features(x, num_joints: int):
    """(..., T, D) features -> (local positions (..., T, J, 3), root velocity (..., T, 3))."""
    return x[..., :3 * num_joints].reshape(x.shape[:-1] + (num_joints, 3)), x[..., 3 * num_joints:]


def integrate_root(vel: np.ndarray, ref0, yaw0: float):
    """Integrate root velocities back into a trajectory.

    vel: (T, 3) ``(vx, vz, w)`` per frame; ref0: (2,) floor position at frame 0; yaw0: yaw at frame 0.
    Returns ``(ref (T, 2), yaw (T,))`` with ``yaw_t = yaw_{t-1} + w_t``, ``r_t = r_{t-1} + R(yaw_{t-1}) v_t``.
    """
    vel = np.asarray(vel, np.float64)
    yaw = yaw0 + np.concatenate([[0.0], np.cumsum(vel[1:, 2])])
    steps = yaw_rotate(vel[1:, :2], yaw[:-1])
    ref = np.asarray(ref0, np.float64)[None] + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    return ref, yaw


def features_to_global(x: np.ndarray, num_joints: int, ref0, yaw0: float) -> np.ndarray:
    """(T, D) un-normalised features -> (T, J, 3) global positions (root trajectory integrated)."""
    local, vel = split_features(np.asarray(x, np.float64), num_joints)
    ref, yaw = integrate_root(vel, ref0, yaw0)
    xz = yaw_rotate(local[..., [0, 2]], yaw[:, None])
    return np.stack([xz[..., 0] + ref[:, None, 0], local[..., 1], xz[..., 1] + ref[:, None, 1]], axis=-1)


@dataclasses.dataclass
class ClipBank:
    """All training frames, normalised, and the valid clip starts.

    frames: (F, D) float32 normalised features of every motion, concatenated;
    starts: (N,) int64 first frame of every clip of ``clip_length`` that stays inside one motion;
    normalizer: per-row statistics (mean, std: (D,)); num_joints: J.
    """

    frames: np.ndarray
    starts: np.ndarray
    clip_length: int
    normalizer: Normalizer
    num_joints: int

    def clips(self, idx) -> np.ndarray:
        """Clips ``starts[idx]`` as images: (len(idx), D, clip_length) float32."""
        s = self.starts[np.asarray(idx)]
        win = self.frames[s[:, None] + np.arange(self.clip_length)[None]]   # (B, T, D)
        return np.ascontiguousarray(np.swapaxes(win, 1, 2))


def build_clip_bank(feats: Sequence[MotionFeatures], clip_length: int, normalizer: Normalizer | None = None,
                    std_eps: float = 1e-3) -> ClipBank:
    """Stack motions into a :class:`ClipBank`; fits the per-row normaliser when none is given."""
    usable = [f for f in feats if f.features.shape[0] >= clip_length]
    if not usable:
        raise ValueError(f"no motion has {clip_length} frames")
    if normalizer is None:
        normalizer = Normalizer.fit(np.concatenate([f.features for f in usable]), eps=std_eps)
    frames, starts, offset = [], [], 0
    for f in usable:
        n = f.features.shape[0]
        frames.append(normalizer(f.features).astype(np.float32))
        starts.append(offset + np.arange(n - clip_length + 1))
        offset += n
    num_joints = (usable[0].features.shape[1] - 3) // 3
    return ClipBank(np.concatenate(frames), np.concatenate(starts), int(clip_length), normalizer, num_joints)


def curriculum_mu(epoch, start: float = 10.0, end: float = 120.0, step: float = 10.0, every: int = 5):
    """Mean gap length at ``epoch`` (0-based): ``min(end, start + step * (epoch // every))``."""
    return min(float(end), float(start) + float(step) * (int(epoch) // int(every)))


def gap_mask(key, batch: int, length: int, mu, sigma):
    """One gap of whole columns per clip: length ``round(N(mu, sigma^2))`` clipped to [1, T-1], start
    uniform in [0, T - length].  Returns ``(mask (B, T) float32, 1 = known / 0 = missing, gap_len (B,))``.
    """
    k1, k2 = jax.random.split(key)
    lam = jnp.round(mu + sigma * jax.random.normal(k1, (batch,)))
    lam = jnp.clip(lam, 1, length - 1).astype(jnp.int32)
    tau = jnp.floor(jax.random.uniform(k2, (batch,)) * (length - lam + 1)).astype(jnp.int32)
    t = jnp.arange(length)[None]
    missing = (t >= tau[:, None]) & (t < (tau + lam)[:, None])
    return 1.0 - missing.astype(jnp.float32), lam


def joint_row_mask(key, batch: int, num_joints: int, max_joints: int = 3):
    """1..max_joints distinct non-root joints per clip, missing over the whole clip.

    Returns (B, J) float32, 1 = known / 0 = missing (joint 0, the root, is never removed).
    """
    k1, k2 = jax.random.split(key)
    n = jax.random.randint(k1, (batch, 1), 1, max_joints + 1)
    score = jax.random.uniform(k2, (batch, num_joints)).at[:, 0].set(2.0)   # root ranks last
    rank = jnp.argsort(jnp.argsort(score, axis=1), axis=1)
    return 1.0 - (rank < n).astype(jnp.float32)


def frames_to_rows_mask(frame_mask=None, joint_mask=None, num_joints: int = 0, length: int = 0):
    """Combine a column mask (B, T) and / or a joint mask (B, J) or (B, J, T) into an image mask (B, D, T).

    Joint masks hide the joint's 3 rows; the 3 root-velocity rows follow only the column mask.
    """
    parts = []
    if joint_mask is not None:
        jm = joint_mask if joint_mask.ndim == 3 else joint_mask[..., None] * jnp.ones((length,))
        b = jm.shape[0]
        rows = jnp.repeat(jm, 3, axis=1)                                       # (B, 3J, T)
        rows = jnp.concatenate([rows, jnp.ones((b, 3, rows.shape[-1]), rows.dtype)], axis=1)
        parts.append(rows)
    if frame_mask is not None:
        parts.append(frame_mask[:, None, :] * jnp.ones((3 * num_joints + 3, 1)))
    out = parts[0]
    for p in parts[1:]:
        out = out * p
    return out


def training_mask(key, batch: int, num_joints: int, length: int, mu, sigma, p_joint: float = 0.3,
                  max_joints: int = 3):
    """The paper's training corruption: per clip, with probability ``1 - p_joint`` one gap of columns
    (:func:`gap_mask`), otherwise 1-3 joints removed over the whole clip (:func:`joint_row_mask`).

    Returns (B, D, T) float32 with 1 = known, 0 = removed (the model sees ``x * mask``).
    """
    k1, k2, k3 = jax.random.split(key, 3)
    cols, _ = gap_mask(k1, batch, length, mu, sigma)
    col_img = frames_to_rows_mask(frame_mask=cols, num_joints=num_joints, length=length)
    row_img = frames_to_rows_mask(joint_mask=joint_row_mask(k2, batch, num_joints, max_joints),
                                  num_joints=num_joints, length=length)
    use_rows = jax.random.uniform(k3, (batch, 1, 1)) < p_joint
    return jnp.where(use_rows, row_img, col_img)
