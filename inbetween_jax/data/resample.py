"""Frame-rate conversion of motions (pure NumPy).

Window lengths, offsets and per-frame thresholds of the data layer are in frames at one working rate
(:data:`WORKING_FPS`, the LaFAN1 and embedded-data rate), so motions captured at another rate are resampled
to it when loaded: frame ``k`` of the result is the motion at time ``k / fps`` seconds, rotations slerped and
positions linearly interpolated between the two source frames around it.  When the source rate is an integer
multiple of the target (120 -> 30 Hz) every sample falls on a source frame and the result is an exact
subsample.  :func:`fill_unknown` interpolates the same way across runs of unknown frames (a generated motion put
back on a user's rig keeps the user's values there).
"""
from __future__ import annotations

import dataclasses

import numpy as np

WORKING_FPS = 30.0
# BVH writers round "Frame Time" (0.008333 for 120 Hz, 0.033333 for 30 Hz); a rate within this relative
# distance of an integer is taken as that integer (29.97 Hz video rates count as 30).
_NOMINAL_RTOL = 2e-3
FRAME_TOL = 1e-3        # frames: a rate stored a little off (30.000012) must not move a frame number by one


def nominal_fps(frame_time: float) -> float:
    """The frame rate a BVH ``Frame Time`` stands for: ``1 / frame_time``, snapped to the nearest integer
    when within 0.2 % of it (``0.008333`` -> 120.0, ``0.0333333`` -> 30.0, ``0.02`` -> 50.0)."""
    if not np.isfinite(frame_time) or frame_time <= 0:
        raise ValueError(f"frame time must be positive, got {frame_time!r}")
    fps = 1.0 / float(frame_time)
    near = round(fps)
    return float(near) if near >= 1 and abs(fps - near) <= _NOMINAL_RTOL * fps else fps


def sample_times(num_frames: int, src_fps: float, fps: float) -> np.ndarray:
    """Fractional source-frame positions of the output frames: ``k * src_fps / fps`` for
    ``k = 0, 1, ...`` while inside ``[0, num_frames - 1]``. Returns (K,) float64."""
    if num_frames < 1:
        raise ValueError("cannot resample a motion without frames")
    ratio = src_fps / fps
    count = int(np.floor((num_frames - 1) / ratio + 1e-9)) + 1
    return np.arange(count) * ratio


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation along the shorter arc.

    q0, q1: (..., 4) unit quaternions (w, x, y, z); t: broadcastable to (...). Returns (..., 4) unit
    quaternions (normalised linear blend where the two are within 1e-6 rad, where slerp equals it).
    """
    q0, q1 = np.asarray(q0, np.float64), np.asarray(q1, np.float64)
    t = np.asarray(t, np.float64)
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where((dot < 0)[..., None], -q1, q1)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    omega = np.arccos(dot)
    sin_om = np.sin(omega)
    near = sin_om < 1e-6
    safe = np.where(near, 1.0, sin_om)
    w0 = np.where(near, 1.0 - t, np.sin((1.0 - t) * omega) / safe)
    w1 = np.where(near, t, np.sin(t * omega) / safe)
    q = w0[..., None] * q0 + w1[..., None] * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _sign_continuous(q: np.ndarray) -> np.ndarray:
    """Flip quaternions (T, J, 4) so consecutive frames have non-negative dot products."""
    if q.shape[0] < 2:
        return q
    flip = np.sum(q[1:] * q[:-1], axis=-1) < 0
    odd = np.concatenate([np.zeros_like(flip[:1]), np.cumsum(flip, axis=0) % 2 == 1], axis=0)
    sign = np.where(odd, -1.0, 1.0)
    return q * sign[..., None]


def resample_motion(motion, fps: float = WORKING_FPS):
    """``motion`` (a :class:`~inbetween_jax.data.bvh.Motion`) at ``fps`` frames per second.

    The source rate is :func:`nominal_fps` of ``motion.frame_time`` (``fps`` is snapped the same way); when it
    already equals ``fps`` the motion is returned unchanged.  Otherwise output frame ``k`` is time ``k / fps``:
    local rotations (T, J, 4) slerped and local positions (T, J, 3) (root trajectory, animated position
    channels) linearly interpolated between the neighbouring source frames; the result covers the source's duration
    (``floor((T - 1) * fps / src_fps) + 1`` frames) and has ``frame_time = 1 / fps``.
    """
    fps = float(fps)
    if not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"target frame rate must be positive, got {fps!r}")
    fps = nominal_fps(1.0 / fps)          # a rate stored as 30.000012 is 30: 120 -> 30 stays a plain subsample
    src = nominal_fps(motion.frame_time)
    if abs(src - fps) <= _NOMINAL_RTOL * fps:
        return motion
    q = np.asarray(motion.local_quats, np.float64)
    p = np.asarray(motion.local_pos, np.float64)
    u = sample_times(q.shape[0], src, fps)
    i0 = np.floor(u + 1e-9).astype(np.int64)
    w = u - i0
    w[np.abs(w) < 1e-9] = 0.0
    i0 = np.minimum(i0, q.shape[0] - 1)
    i1 = np.minimum(i0 + 1, q.shape[0] - 1)
    quats = slerp(q[i0], q[i1], w[:, None])
    exact = w == 0.0
    quats[exact] = q[i0[exact]]  # integer ratios: a plain subsample, bit for bit
    pos = p[i0] + w[:, None, None] * (p[i1] - p[i0])
    return dataclasses.replace(motion, local_quats=_sign_continuous(quats), local_pos=pos, frame_time=1.0 / fps)


__all__ = ["WORKING_FPS", "FRAME_TOL", "nominal_fps", "resample_motion", "sample_times", "slerp", "check_tempo",
           "fill_unknown", "known_frames"]


def check_tempo(tempo) -> tuple:
    """``data.tempo`` (the speeds of a model's tempo copies) as floats.

    Raises:
        ValueError: a speed that is not positive (one line).
    """
    speeds = tuple(float(s) for s in tempo)
    if any(not s > 0 for s in speeds):
        raise ValueError(f"data.tempo: speeds must be positive, got {list(tempo)}")
    return speeds


def fill_unknown(values, known, rotations: bool):
    """(T, J, C) ``values`` with every run of unknown frames (``known`` (T,) bool False) interpolated between
    the known frames around it (slerp for rotations, C=4; lerp otherwise); held at the clip's ends."""
    out = np.array(values, np.float64, copy=True)
    known = np.asarray(known, bool)
    idx = np.flatnonzero(known)
    if len(idx) == 0:
        raise ValueError("fill_unknown: no known frame")
    t = np.arange(len(out))
    hi = np.clip(np.searchsorted(idx, t), 0, len(idx) - 1)
    lo = np.clip(hi - 1, 0, len(idx) - 1)
    a, b = idx[lo], idx[hi]
    a = np.where(a > t, b, a)                      # before the first known frame: hold it
    b = np.where(b < t, a, b)                      # after the last: hold it
    w = np.where(b > a, (t - a) / np.maximum(b - a, 1), 0.0)
    miss = ~known
    if rotations:
        out[miss] = slerp(out[a[miss]], out[b[miss]], w[miss][:, None])
    else:
        out[miss] = out[a[miss]] + w[miss][:, None, None] * (out[b[miss]] - out[a[miss]])
    return out


def known_frames(generated, user, known, caller: str) -> np.ndarray:
    """(T,) bool: ``known`` (default: the first and the last frame) for a generated motion put back on ``user``'s
    rig; raises ValueError (naming ``caller``) when the two frame counts differ."""
    t_len = generated.num_frames
    if user.num_frames != t_len:
        raise ValueError(f"{caller}: {t_len} generated frames but {user.num_frames} user frames")
    if known is None:
        known = np.zeros(t_len, bool)
        known[[0, -1]] = True
    return np.asarray(known, bool)
