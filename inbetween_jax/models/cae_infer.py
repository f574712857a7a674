"""Inference with the convolutional inpainting AE: corruptions, filling, errors, trajectories and BVH.

Every function works on one clip image ``(D, T)`` or a batch ``(B, D, T)`` of *normalised* features, with
masks of the same shape (1 = known, 0 = missing), for any T (the model is fully convolutional).

* masks: :func:`gap_frames` (several gaps of any length), :func:`dropout_mask` (each joint dropped per frame
  with probability p), :func:`joints_mask` (joints missing over the whole clip);
* :func:`add_position_noise` (Gaussian noise on the joint-position rows, in normalised units);
* :func:`fill` runs the model on ``x * mask`` (raw outputs, as the paper; ``keep_known=True`` pastes the
  known entries back); :func:`linear_fill` is the linear-interpolation baseline;
* :func:`joint_errors` -- the paper's root-aligned 3D joint error (cm) over selected frames;
* :func:`to_global` integrates the root velocities back into a trajectory (optionally stitched to the known
  trajectory at the gap ends) and :func:`fit_rotations` turns positions back into BVH rotations.
"""
from __future__ import annotations

import numpy as np

from inbetween_jax.geometry import bone_lengths, forward_kinematics, quat_between, quat_inv, quat_mul, quat_rotate
from inbetween_jax.geometry import quat_normalize, quat_slerp
from inbetween_jax.geometry.fit import fit_rotations  # noqa: F401  (moved; kept importable here)
from inbetween_jax.models.cae_data import features_to_global, integrate_root, split_features, yaw_rotate

__all__ = ["gap_frames", "frame_mask_image", "dropout_mask", "joints_mask", "add_position_noise", "fill",
           "linear_fill", "joint_errors", "bone_length_stats", "to_global", "fit_rotations", "gap_ranges"]


def gap_frames(length: int, gaps) -> np.ndarray:
    """(T,) float32 frame mask with the ``[(start, stop), ...]`` frame ranges missing (stop exclusive)."""
    m = np.ones(int(length), np.float32)
    for a, b in gaps:
        if not 0 <= a < b <= length:
            raise ValueError(f"gap ({a}, {b}) is outside 0..{length}")
        m[a:b] = 0.0
    return m


def gap_ranges(frame_mask) -> list:
    """Inverse of :func:`gap_frames`: ``[(start, stop), ...]`` of the runs of zeros in a (T,) mask."""
    miss = np.concatenate([[0], (np.asarray(frame_mask) < 0.5).astype(np.int8), [0]])
    d = np.diff(miss)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def frame_mask_image(frame_mask, num_joints: int) -> np.ndarray:
    """(..., T) frame mask -> (..., D, T) image mask (all rows of a missing frame missing)."""
    fm = np.asarray(frame_mask, np.float32)
    return np.repeat(fm[..., None, :], 3 * num_joints + 3, axis=-2)


def _joint_rows(jm, num_joints: int) -> np.ndarray:
    """(..., J, T) joint mask -> (..., D, T) (root-velocity rows known)."""
    rows = np.repeat(np.asarray(jm, np.float32), 3, axis=-2)
    ones = np.ones(rows.shape[:-2] + (3, rows.shape[-1]), np.float32)
    return np.concatenate([rows, ones], axis=-2)


def dropout_mask(rng: np.random.Generator, shape_bt, num_joints: int, p: float) -> np.ndarray:
    """Each joint of each frame missing independently with probability ``p``.

    shape_bt: ``(T,)`` or ``(B, T)``. Returns (..., D, T) float32.
    """
    shape_bt = tuple(shape_bt)
    keep = rng.random(shape_bt[:-1] + (num_joints, shape_bt[-1])) >= p
    return _joint_rows(keep, num_joints)


def joints_mask(length: int, num_joints: int, missing) -> np.ndarray:
    """(D, T) mask with the joints ``missing`` (indices) removed over the whole clip."""
    jm = np.ones((num_joints, int(length)), np.float32)
    jm[list(missing)] = 0.0
    return _joint_rows(jm, num_joints)


def add_position_noise(rng: np.random.Generator, x_norm, num_joints: int, sigma: float) -> np.ndarray:
    """Add N(0, sigma^2) to the joint-position rows of normalised clips (..., D, T)."""
    x = np.array(x_norm, np.float32, copy=True)
    x[..., :3 * num_joints, :] += sigma * rng.standard_normal(x[..., :3 * num_joints, :].shape).astype(np.float32)
    return x


def fill(model, x_norm, mask, keep_known: bool = False, chunk: int = 64) -> np.ndarray:
    """Model reconstruction of ``x_norm * mask``: (B, D, T) or (D, T) -> same shape.

    ``model`` is a :class:`~inbetween_jax.models.cae_train.TrainedCAE` (or any object with ``predict``).
    """
    x = np.asarray(x_norm, np.float32)
    single = x.ndim == 2
    xb = (x * mask)[None] if single else x * mask
    out = np.concatenate([np.asarray(model.predict(xb[i:i + chunk])) for i in range(0, len(xb), chunk)])
    out = out[0] if single else out
    if keep_known:
        out = np.where(np.asarray(mask) > 0.5, x, out)
    return out


def linear_fill(x_norm, mask) -> np.ndarray:
    """Linear-interpolation baseline: every row's missing entries interpolated in time between its nearest
    known entries (held constant before the first / after the last); a row with nothing known gets 0 (the
    training mean).  (..., D, T) -> (..., D, T).
    """
    x = np.asarray(x_norm, np.float32)
    m = np.broadcast_to(np.asarray(mask) > 0.5, x.shape)
    flat, fm = x.reshape(-1, x.shape[-1]), m.reshape(-1, x.shape[-1])
    out = flat.copy()
    t = np.arange(x.shape[-1])
    for i in np.flatnonzero(~fm.all(axis=1)):
        k = fm[i]
        out[i] = np.interp(t, t[k], flat[i, k]) if k.any() else 0.0
    return out.reshape(x.shape)


def joint_errors(pred_norm, target_norm, normalizer, num_joints: int, frames=None) -> np.ndarray:
    """Root-aligned 3D joint errors (cm): the Euclidean distance of every joint's body-frame position.

    pred_norm, target_norm: (B, D, T) normalised; frames: (B, T) bool selecting the scored frames (default
    all).  Returns a flat array with one error per (selected frame, joint).
    """
    p = normalizer.inverse(np.swapaxes(np.asarray(pred_norm, np.float64), -1, -2))
    g = normalizer.inverse(np.swapaxes(np.asarray(target_norm, np.float64), -1, -2))
    pp, _ = split_features(p, num_joints)
    gg, _ = split_features(g, num_joints)
    err = np.linalg.norm(pp - gg, axis=-1)                 # (B, T, J)
    if frames is not None:
        err = err[np.asarray(frames, bool)]
    return err.reshape(-1)


def bone_length_stats(x_norm, normalizer, num_joints: int, parents, frames=None) -> np.ndarray:
    """Bone lengths (cm) of body-frame positions: (B, D, T) -> (N, J-1) over the selected frames."""
    f = normalizer.inverse(np.swapaxes(np.asarray(x_norm, np.float64), -1, -2))
    pos, _ = split_features(f, num_joints)
    bl = bone_lengths(pos, parents)                        # (B, T, J-1)
    if frames is not None:
        bl = bl[np.asarray(frames, bool)]
    return bl.reshape(-1, num_joints - 1)


def to_global(y_norm, normalizer, num_joints: int, ref0, yaw0: float, known_feats=None, frame_mask=None):
    """One clip (D, T) normalised -> (T, J, 3) global positions.

    Without ``known_feats``: the predicted root velocities are integrated from ``(ref0, yaw0)`` at frame 0.
    With ``known_feats`` ((T, D) un-normalised input features) and ``frame_mask`` ((T,), 1 = known), the known
    frames keep the input trajectory and each gap integrates the predicted velocities from the frame before
    it, with the end mismatch spread linearly over the gap (so the path meets the next known frame).
    """
    y = normalizer.inverse(np.asarray(y_norm, np.float64).T)
    if known_feats is None:
        return features_to_global(y, num_joints, ref0, yaw0)
    _, vk = split_features(np.asarray(known_feats, np.float64), num_joints)
    _, vy = split_features(y, num_joints)
    ref, yaw = integrate_root(vk, ref0, yaw0)
    t_len = len(ref)
    for a, b in gap_ranges(frame_mask):
        start = max(a - 1, 0)
        seg_ref, seg_yaw = integrate_root(vy[start:b + 1] if b < t_len else vy[start:b],
                                          ref[start] if a > 0 else ref0, yaw[start] if a > 0 else yaw0)
        n = b - a
        if b < t_len:  # spread the mismatch at the known frame b over the gap
            w = (np.arange(1, n + 1) / (n + 1))[:, None]
            d_ref, d_yaw = ref[b] - seg_ref[-1], yaw[b] - seg_yaw[-1]
            seg_ref, seg_yaw = seg_ref[:-1], seg_yaw[:-1]
        else:
            w, d_ref, d_yaw = np.zeros((n, 1)), np.zeros(2), 0.0
        off = 1 if a > 0 else 0
        ref[a:b] = seg_ref[off:off + n] + w * d_ref
        yaw[a:b] = seg_yaw[off:off + n] + w[:, 0] * d_yaw
    local, _ = split_features(y, num_joints)
    xz = yaw_rotate(local[..., [0, 2]], yaw[:, None])
    return np.stack([xz[..., 0] + ref[:, None, 0], local[..., 1], xz[..., 1] + ref[:, None, 1]], axis=-1)


def slerp_gaps(local_quats, frame_mask) -> np.ndarray:
    """(T, J, 4) rotations with every gap replaced by a slerp between the frames around it (held at ends)."""
    q = np.array(local_quats, np.float64, copy=True)
    t_len = len(q)
    for a, b in gap_ranges(frame_mask):
        q0 = q[a - 1] if a > 0 else q[min(b, t_len - 1)]
        q1 = q[b] if b < t_len else q0
        w = (np.arange(a, b) - (a - 1)) / (b - a + 1)
        q[a:b] = quat_slerp(np.broadcast_to(q0, (b - a,) + q0.shape), np.broadcast_to(q1, (b - a,) + q1.shape),
                            w[:, None])
    return q


def check_fk_positions(local_quats, local_pos, parents):
    """FK positions (T, J, 3) of a (T, J, 4) / (T, J, 3) motion (helper for tests and the CLI)."""
    return forward_kinematics(np.asarray(local_quats, np.float64), np.asarray(local_pos, np.float64), parents)[1]


def process_motion(model, motion, gaps=(), noise: float = 0.0, dropout: float = 0.0, joints=(), seed: int = 0,
                   keep_known: bool = False) -> dict:
    """Corrupt a whole :class:`~inbetween_jax.data.Motion` (any length), fill it with ``model`` and convert back.

    gaps: ``[(start, stop), ...]`` frames to remove; noise: sigma (normalised units) on the position rows;
    dropout: per-frame joint dropout probability; joints: joint names or indices missing over the whole clip.
    Returns ``{"positions": (T, J, 3) global positions, "motion": Motion with fitted rotations,
    "frames": (T,) bool frames refitted, "error_cm": (mean, std) vs the input over the corrupted frames,
    "fk_gap_cm": mean distance between the BVH's FK and the predicted positions on those frames}``.
    """
    import dataclasses

    from inbetween_jax.models.cae_data import motion_features

    skel, j = model.skeleton, model.num_joints
    if not motion.skeleton.same_topology(skel):
        raise ValueError(f"{motion.source}: skeleton differs from the checkpoint's ({skel.num_joints} joints)")
    t_len = motion.num_frames
    feats = motion_features(motion)
    x = model.normalizer(feats.features).T.astype(np.float32)            # (D, T)
    rng = np.random.default_rng(seed)
    fm = gap_frames(t_len, gaps)
    mask = frame_mask_image(fm, j)
    if joints:
        idx = [skel.index(n) if isinstance(n, str) else int(n) for n in joints]
        mask = mask * joints_mask(t_len, j, idx)
    if dropout > 0:
        mask = mask * dropout_mask(rng, (t_len,), j, dropout)
    x_in = add_position_noise(rng, x, j, noise) if noise > 0 else x
    y = fill(model, x_in, mask, keep_known=keep_known)
    pos = to_global(y, model.normalizer, j, feats.ref0, feats.yaw0, known_feats=feats.features, frame_mask=fm)
    scored = (fm < 0.5) if gaps else np.ones(t_len, bool)     # gaps: their frames; otherwise every frame
    err = joint_errors(y[None], x[None], model.normalizer, j, scored[None])
    refit = scored
    ref_q = slerp_gaps(motion.local_quats, fm)
    lq, lp = fit_rotations(pos, ref_q, motion.local_pos, skel.parents, refit)
    out = dataclasses.replace(motion, local_quats=lq, local_pos=lp)
    fk = check_fk_positions(lq, lp, skel.parents)
    fk_gap = float(np.linalg.norm(fk - pos, axis=-1)[refit].mean()) if refit.any() else 0.0
    return {"positions": pos.astype(np.float32), "motion": out, "frames": refit,
            "error_cm": (float(err.mean()), float(err.std())), "fk_gap_cm": fk_gap}
