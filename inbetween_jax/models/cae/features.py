"""The paper's motion representation (Sec. 3.1): motions <-> clip images of feature rows, normalisation
statistics and the clip bank that training draws from.

Representation.  A frame is ``D = 3J + 3`` numbers: the J joints' 3D positions in the character's body
frame (origin at the root joint projected on the floor, Y up, rotated so that the character faces +Z;
joint order as the skeleton, x y z per joint), then the root's floor-plane velocity ``(vx, vz)`` and its
yaw velocity ``w`` (radians).  Velocities are relative to the previous frame and expressed in its body
frame: ``v_t = R(-yaw_{t-1}) (r_t - r_{t-1})``, ``w_t = wrap(yaw_t - yaw_{t-1})``; frame 0 copies frame 1.
The facing (yaw) is Holden et al.'s: the normal of the hips' and shoulders' left-right axis in the floor
plane, Gaussian-smoothed over time (:func:`smoothed_facing_yaw`).  With 22 joints (LaFAN1) D = 69, as the
paper's data.  A clip is an image ``(D, T)`` -- rows are features, columns frames -- normalised per row with
training statistics.  Everything here is host-side NumPy (float64 inside, float32 features out); rotations
about the up axis are :func:`inbetween_jax.geometry.heading.rotate_about_up`.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from inbetween_jax.data.features import Normalizer
from inbetween_jax.data.filters import gaussian_lowpass
from inbetween_jax.geometry.heading import rotate_about_up

__all__ = ["num_features", "MotionFeatures", "smoothed_facing_yaw", "positions_to_features", "body_frame_features",
           "split_features", "body_positions", "integrate_root", "features_to_global", "to_global", "root_base_path", "bound_root_path", "ClipBank",
           "build_clip_bank", "mirror_rows", "mirror_clips"]


def num_features(num_joints: int) -> int:
    """D = 3J + 3."""
    return 3 * int(num_joints) + 3


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
    ref: np.ndarray | None = None       # (T, 2) the root's floor path
    yaw: np.ndarray | None = None       # (T,) the facing, unwrapped (the known frames' track, see body_frame_features)


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


def smoothed_facing_yaw(global_pos: np.ndarray, skeleton, smooth: float = 4.0, known=None) -> np.ndarray:
    """(T, J, 3) global positions -> (T,) facing yaw (``atan2(fx, fz)``, yaw 0 faces +Z).

    As Holden et al.: across = sum of (left - right) over the hip joints and the shoulders, forward =
    across x up, Gaussian-smoothed over time (``smooth`` frames std) before the angle is taken.  known: optional
    (T,) bool; the smoothing then reads those frames only (:func:`~inbetween_jax.data.filters.gaussian_lowpass`),
    so no frame's facing depends on an unknown one.
    """
    gp = np.asarray(global_pos, np.float64)
    across = sum(gp[:, a] - gp[:, b] for a, b in _side_joints(skeleton))
    fwd = np.stack([-across[:, 2], across[:, 0]], axis=-1)            # (fx, fz) = across x (0, 1, 0)
    if smooth > 0 and len(fwd) > 1:
        fwd = gaussian_lowpass(fwd, smooth, 0, np.float64, known=known)
    return np.arctan2(fwd[:, 0], fwd[:, 1])


def positions_to_features(global_pos: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(T, J, 3) global positions + (T,) yaw -> (T, 3J + 3) features (see module docstring). T >= 2."""
    gp = np.asarray(global_pos, np.float64)
    t, j, _ = gp.shape
    ref = gp[:, 0, [0, 2]]                                         # (T, 2) root floor projection
    rel = gp.copy()
    rel[..., 0] -= ref[:, None, 0]
    rel[..., 2] -= ref[:, None, 1]
    loc_xz = rotate_about_up(rel[..., [0, 2]], -yaw[:, None])
    local = np.stack([loc_xz[..., 0], rel[..., 1], loc_xz[..., 1]], axis=-1)  # (T, J, 3)
    vel = np.zeros((t, 3))
    if t > 1:
        vel[1:, :2] = rotate_about_up(ref[1:] - ref[:-1], -yaw[:-1])
        vel[1:, 2] = _wrap(yaw[1:] - yaw[:-1])
        vel[0] = vel[1]
    return np.concatenate([local.reshape(t, 3 * j), vel], axis=1).astype(np.float32)


def body_frame_features(motion, smooth: float = 4.0, known=None) -> MotionFeatures:
    """A :class:`~inbetween_jax.data.Motion` -> :class:`MotionFeatures` (FK through the shared geometry).

    known: optional (T,) bool, the frames that may be read (``inbetween infill``: all but the gaps).  Then no
    known frame's features depend on an unknown frame: the facing is smoothed over known frames only, and a
    known frame right after an unknown one (or frame 0) takes its root velocity from the step to the next frame
    (0 if that one is unknown too), as frame 0 always does.  The unknown frames' own features still come from
    their content; the caller masks them.  ``ref`` / ``yaw`` hold the root's floor path and unwrapped facing.
    """
    gp = motion.global_positions()
    yaw = smoothed_facing_yaw(gp, motion.skeleton, smooth, known=known)
    feats = positions_to_features(gp, yaw)
    if known is not None:
        k = np.asarray(known, bool).reshape(-1)
        after = k & ~np.concatenate([[False], k[:-1]])                  # known, previous frame unknown or none
        nxt_ok = np.concatenate([k[1:], [False]])
        for t in np.flatnonzero(after):
            feats[t, -3:] = feats[t + 1, -3:] if nxt_ok[t] else 0.0
    return MotionFeatures(feats, gp[0, 0, [0, 2]].astype(np.float64), float(yaw[0]), gp.astype(np.float32),
                          getattr(motion, "source", ""), ref=gp[:, 0, [0, 2]].astype(np.float64),
                          yaw=np.unwrap(yaw))


def mirror_rows(skeleton) -> tuple:
    """The left-right mirror of the representation as a signed row permutation: ``(perm (D,), sign (D,))`` with
    ``mirrored[r] = sign[r] * features[perm[r]]`` (un-normalised).  The body frame's x axis is the character's
    side, so a mirror negates every joint's x and swaps left and right joints (``Skeleton.mirror_map``, by name);
    the root's side velocity ``vx`` and yaw velocity ``w`` change sign, ``vz`` does not.

    Raises:
        UserError: the skeleton has no left/right joint pair by name (a mirror would not be a body).
    """
    from inbetween_jax.errors import UserError
    twin = np.asarray(skeleton.mirror_map(), np.int64)
    if np.all(twin == np.arange(len(twin))):
        raise UserError("mirroring needs left/right joints named Left*/Right* (or l*/r*); this skeleton has none")
    j = len(twin)
    perm = np.concatenate([(3 * twin[:, None] + np.arange(3)[None]).reshape(-1), 3 * j + np.arange(3)])
    sign = np.concatenate([np.tile([-1.0, 1.0, 1.0], j), [-1.0, 1.0, -1.0]])
    return perm, sign.astype(np.float32)


def mirror_clips(x_norm, perm, sign, normalizer: Normalizer):
    """Normalised clip images (..., D, T) of the mirrored motion (:func:`mirror_rows`); NumPy or jax arrays.
    An involution: mirroring twice returns the input (up to float rounding)."""
    mean, std = np.asarray(normalizer.mean)[:, None], np.asarray(normalizer.std)[:, None]
    raw = x_norm[..., perm, :] * std[perm] + mean[perm]
    return (sign[:, None] * raw - mean) / std


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
    steps = rotate_about_up(vel[1:, :2], yaw[:-1])
    ref = np.asarray(ref0, np.float64)[None] + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    return ref, yaw


def features_to_global(x: np.ndarray, num_joints: int, ref0, yaw0: float) -> np.ndarray:
    """(T, D) un-normalised features -> (T, J, 3) global positions (root trajectory integrated)."""
    local, vel = split_features(np.asarray(x, np.float64), num_joints)
    ref, yaw = integrate_root(vel, ref0, yaw0)
    xz = rotate_about_up(local[..., [0, 2]], yaw[:, None])
    return np.stack([xz[..., 0] + ref[:, None, 0], local[..., 1], xz[..., 1] + ref[:, None, 1]], axis=-1)


def body_positions(x_norm, normalizer: Normalizer, num_joints: int) -> np.ndarray:
    """Normalised clip images (..., D, T) -> body-frame joint positions (..., T, J, 3), float64 (cm)."""
    f = normalizer.inverse(np.swapaxes(np.asarray(x_norm, np.float64), -1, -2))
    return split_features(f, num_joints)[0]


def to_global(y_norm, normalizer: Normalizer, num_joints: int, ref0, yaw0: float, known_feats=None, frame_mask=None,
              root_bound: float = 0.0, known_track=None, root_edge_fade: float = 0.0):
    """One clip (D, T) normalised -> (T, J, 3) global positions.

    Without ``known_feats``: the predicted root velocities are integrated from ``(ref0, yaw0)`` at frame 0.
    With ``known_feats`` ((T, D) un-normalised input features) and ``frame_mask`` ((T,), 1 = known), the known
    frames keep the input trajectory and each gap integrates the predicted velocities from the frame before
    it, with the end mismatch spread linearly over the gap (so the path meets the next known frame).
    ``root_bound`` > 0 (data units; with ``known_feats``): the root's floor path in the gaps stays within that
    distance of :func:`root_base_path`, the limited cubic Hermite through the known root positions (a deviation
    d becomes ``d min(1, root_bound / |d|)``), so an integrated path cannot run ahead of the motion and back;
    ``root_edge_fade``: that base path's edge tangents, as :func:`root_base_path` says.
    known_track: optional ``(ref (T, 2), yaw (T,))``, the known frames' root path and unwrapped facing
    (``MotionFeatures.ref`` / ``.yaw``), used instead of integrating ``known_feats``' velocities (whose first
    velocity after a gap no longer reads the gap when the features were built with ``known``).
    """
    from inbetween_jax.models.cae.masks import gap_ranges
    y = normalizer.inverse(np.asarray(y_norm, np.float64).T)
    if known_feats is None and known_track is None:
        return features_to_global(y, num_joints, ref0, yaw0)
    _, vy = split_features(y, num_joints)
    if known_track is not None:
        ref, yaw = (np.array(v, np.float64) for v in known_track)
    else:
        ref, yaw = integrate_root(split_features(np.asarray(known_feats, np.float64), num_joints)[1], ref0, yaw0)
    t_len = len(ref)
    for a, b in gap_ranges(frame_mask):
        start = max(a - 1, 0)
        # a leading gap starts from the known frame b's position (the path is hung from it below), so frame 0's
        # position, which lies in the gap, does not enter even by rounding
        start_ref = ref[start] if a > 0 else (ref[b] if b < t_len else ref0)
        seg_ref, seg_yaw = integrate_root(vy[start:b + 1] if b < t_len else vy[start:b], start_ref,
                                          yaw[start] if a > 0 else yaw0)
        n = b - a
        if b < t_len:  # spread the mismatch at the known frame b over the gap (a leading gap: the whole of it,
            # so the path hangs from frame b and never from frame 0, which lies in the gap)
            w = (np.arange(1, n + 1) / (n + 1))[:, None] if a > 0 else np.ones((n, 1))
            d_ref, d_yaw = ref[b] - seg_ref[-1], yaw[b] - seg_yaw[-1]
            seg_ref, seg_yaw = seg_ref[:-1], seg_yaw[:-1]
        else:
            w, d_ref, d_yaw = np.zeros((n, 1)), np.zeros(2), 0.0
        off = 1 if a > 0 else 0
        ref[a:b] = seg_ref[off:off + n] + w * d_ref
        yaw[a:b] = seg_yaw[off:off + n] + w[:, 0] * d_yaw
    if root_bound > 0:
        ref = bound_root_path(ref, frame_mask, root_bound, root_edge_fade)
    local, _ = split_features(y, num_joints)
    xz = rotate_about_up(local[..., [0, 2]], yaw[:, None])
    return np.stack([xz[..., 0] + ref[:, None, 0], local[..., 1], xz[..., 1] + ref[:, None, 1]], axis=-1)


def root_base_path(ref, frame_mask, edge_fade: float = 0.0) -> np.ndarray:
    """(T, 2) floor path with every gap (``frame_mask`` (T,) 0) bridged by the limited cubic Hermite of the known
    positions (:func:`inbetween_jax.baselines.hermite_fill`: velocities matched at the gap's edges, no overshoot
    past the secant per axis; a straight line stays straight).  ``edge_fade`` k > 0: the part of an edge velocity
    the limiter cut fades back in as ``exp(-k frames)`` (``hermite_fill(edge_fade=k)``), so the root leaves and
    reaches each keyframe at the capture's speed."""
    from inbetween_jax.baselines.hermite_fill import hermite_fill
    ref = np.asarray(ref, np.float64)
    known = np.asarray(frame_mask)[None] > 0.5
    return np.asarray(hermite_fill(ref.T, known, edge_fade=edge_fade), np.float64).T


def bound_root_path(ref, frame_mask, bound: float, edge_fade: float = 0.0) -> np.ndarray:
    """(T, 2) floor path whose gap frames are pulled to within ``bound`` of :func:`root_base_path`."""
    ref = np.asarray(ref, np.float64)
    base = root_base_path(ref, frame_mask, edge_fade)
    dev = ref - base
    scale = np.minimum(1.0, bound / np.maximum(np.linalg.norm(dev, axis=-1, keepdims=True), 1e-12))
    gap = (np.asarray(frame_mask) < 0.5)[:, None]
    return np.where(gap, base + dev * scale, ref)


def root_path_options(model_cfg) -> dict:
    """``to_global``'s root options of a run's ``cfg.model``: ``root_bound`` (metres in the config, data units
    here) and ``root_edge_fade``."""
    return {"root_bound": float(getattr(model_cfg, "root_bound", 0.0)) * 100.0,
            "root_edge_fade": float(getattr(model_cfg, "root_edge_fade", 0.0))}


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


