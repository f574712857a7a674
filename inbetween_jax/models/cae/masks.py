"""Masks and corruptions of clip images ``(..., D, T)`` (D = 3J + 3 rows: J joints x 3, then 3 root-velocity
rows; see :mod:`inbetween_jax.models.cae.features`).  1 = known, 0 = missing; the model sees ``x * mask``.

Training (Sec. 3.3; pure ``jax.numpy`` with explicit keys, traced inside the jitted step):
:func:`curriculum_mu` (mean gap length per epoch), :func:`gap_mask` (one gap of whole columns),
:func:`joint_row_mask` (1-3 joints missing over the whole clip), :func:`frames_to_rows_mask`,
:func:`training_mask` (the paper's alternation of the two), :func:`matched_gap_lengths` (gap lengths matched
to evaluation, ``data.mask.eval_matched``) and :func:`linear_prefill` (the residual model's linear fill in jnp).

Evaluation and inference (NumPy; ``np.random.Generator`` for the random ones): :func:`gap_frames` /
:func:`gap_ranges` (frame ranges <-> a (T,) frame mask), :func:`frame_mask_image`, :func:`dropout_mask` (each
joint of each frame missing with probability p), :func:`joints_mask` (named joints missing over the whole
clip) and :func:`add_position_noise` (Gaussian noise on the position rows).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["curriculum_mu", "curriculum_end_epoch", "matched_gap_lengths", "linear_prefill", "gap_mask", "joint_row_mask", "frames_to_rows_mask", "training_mask", "gap_frames",
           "gap_ranges", "frame_mask_image", "dropout_mask", "joints_mask", "add_position_noise"]


# ----------------------------------------------------------------------------- training
def curriculum_mu(epoch, start: float = 10.0, end: float = 120.0, step: float = 10.0, every: int = 5):
    """Mean gap length at ``epoch`` (0-based): ``min(end, start + step * (epoch // every))``."""
    return min(float(end), float(start) + float(step) * (int(epoch) // int(every)))


def curriculum_end_epoch(start: float = 10.0, end: float = 120.0, step: float = 10.0, every: int = 5) -> int:
    """First epoch at which :func:`curriculum_mu` reaches ``end`` (0 when ``start >= end``)."""
    if float(start) >= float(end):
        return 0
    return int(np.ceil((float(end) - float(start)) / float(step))) * int(every)


def matched_gap_lengths(key, batch: int, centres=(30, 60, 120), spread: float = 0.25):
    """Gap lengths matched to evaluation: a centre c drawn uniformly from ``centres``, then a length uniform
    on [c (1 - spread), c (1 + spread)] (rounded).  Returns (B,) float32 (not yet clipped to the clip)."""
    k1, k2 = jax.random.split(key)
    c = jnp.asarray(centres, jnp.float32)[jax.random.randint(k1, (batch,), 0, len(centres))]
    u = jax.random.uniform(k2, (batch,), minval=-1.0, maxval=1.0)
    return jnp.round(c * (1.0 + float(spread) * u))


def linear_prefill(x, mask):
    """jnp twin of :func:`inbetween_jax.baselines.linear_fill`: every row's missing entries linearly
    interpolated in time between its nearest known entries, held before the first / after the last, 0 for a
    row with nothing known; known entries are returned unchanged (bit for bit).

    x: (..., D, T); mask: broadcastable to x, 1 = known.  Returns (..., D, T) float32.
    """
    x = jnp.asarray(x, jnp.float32)
    known = jnp.broadcast_to(jnp.asarray(mask) > 0.5, x.shape)
    t_len = x.shape[-1]
    t = jnp.arange(t_len)
    prev = jax.lax.cummax(jnp.where(known, t, -1), axis=x.ndim - 1)             # last known index <= t
    nxt = jax.lax.cummin(jnp.where(known, t, t_len), axis=x.ndim - 1, reverse=True)  # first known >= t
    has_prev, has_next = prev >= 0, nxt < t_len
    xp = jnp.take_along_axis(x, jnp.clip(prev, 0, t_len - 1), axis=-1)
    xn = jnp.take_along_axis(x, jnp.clip(nxt, 0, t_len - 1), axis=-1)
    w = (t - prev) / jnp.maximum(nxt - prev, 1)
    inner = xp + w.astype(jnp.float32) * (xn - xp)
    filled = jnp.where(has_prev & has_next, inner, jnp.where(has_prev, xp, jnp.where(has_next, xn, 0.0)))
    return jnp.where(known, x, filled)


def gap_mask(key, batch: int, length: int, mu, sigma, matched=0.0, centres=(30, 60, 120), spread: float = 0.25):
    """One gap of whole columns per clip: length ``round(N(mu, sigma^2))`` (or, where ``matched`` is 1,
    :func:`matched_gap_lengths`) clipped to [1, T-1], start uniform in [0, T - length].

    Returns ``(mask (B, T) float32, 1 = known / 0 = missing, gap_len (B,))``.
    """
    k1, k2, k3 = jax.random.split(key, 3)
    lam = jnp.round(mu + sigma * jax.random.normal(k1, (batch,)))
    lam = jnp.where(jnp.asarray(matched) > 0.5, matched_gap_lengths(k3, batch, centres, spread), lam)
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
                  max_joints: int = 3, matched=0.0, centres=(30, 60, 120), spread: float = 0.25):
    """The paper's training corruption: per clip, with probability ``1 - p_joint`` one gap of columns
    (:func:`gap_mask`; ``matched`` / ``centres`` / ``spread``: its evaluation-matched lengths), otherwise
    1-3 joints removed over the whole clip (:func:`joint_row_mask`).

    Returns (B, D, T) float32 with 1 = known, 0 = removed (the model sees ``x * mask``).
    """
    k1, k2, k3 = jax.random.split(key, 3)
    cols, _ = gap_mask(k1, batch, length, mu, sigma, matched, centres, spread)
    col_img = frames_to_rows_mask(frame_mask=cols, num_joints=num_joints, length=length)
    row_img = frames_to_rows_mask(joint_mask=joint_row_mask(k2, batch, num_joints, max_joints),
                                  num_joints=num_joints, length=length)
    use_rows = jax.random.uniform(k3, (batch, 1, 1)) < p_joint
    return jnp.where(use_rows, row_img, col_img)


# ----------------------------------------------------------------------------- evaluation / inference
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
