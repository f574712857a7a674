"""Temporal filters of motion signals (pure NumPy)."""
from __future__ import annotations

import numpy as np

__all__ = ["gaussian_lowpass"]


def gaussian_lowpass(x, sigma: float, axis: int, dtype=np.float32, known=None) -> np.ndarray:
    """``x`` filtered along ``axis`` by a normalised Gaussian of ``sigma`` frames, truncated at 3 sigma, the
    edge frames repeated beyond the ends; computed in float64, returned as ``dtype``.

    known: optional (T,) bool along ``axis``: only those frames are read (normalised convolution: the weighted
    sum over known frames divided by their summed weight), so a frame's result does not depend on any unknown
    frame.  A frame with no known frame within 3 sigma takes the result of the nearest frame that has one (all
    frames unknown: ValueError)."""
    r = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    x = np.moveaxis(np.asarray(x, np.float64), axis, -1)
    t_len = x.shape[-1]

    def smooth(v):
        pad = np.concatenate([np.repeat(v[..., :1], r, -1), v, np.repeat(v[..., -1:], r, -1)], -1)
        return sum(w * pad[..., i:i + t_len] for i, w in enumerate(k))
    if known is None:
        return np.moveaxis(smooth(x), -1, axis).astype(dtype)
    m = np.asarray(known, bool).reshape(-1)
    if m.shape != (t_len,):
        raise ValueError(f"known has {m.size} frames, x has {t_len}")
    if not m.any():
        raise ValueError("no known frame to filter")
    den = smooth(m.astype(np.float64))
    out = smooth(np.where(m, x, 0.0)) / np.maximum(den, 1e-300)
    has = den > 1e-12
    if not has.all():                                   # deep inside a long unknown run: the nearest result
        idx, t = np.flatnonzero(has), np.arange(t_len)
        pos = np.searchsorted(idx, t)
        right, left = idx[np.minimum(pos, len(idx) - 1)], idx[np.maximum(pos - 1, 0)]
        out = out[..., np.where(np.abs(left - t) <= np.abs(right - t), left, right)]
    return np.moveaxis(out, -1, axis).astype(dtype)
