"""Linear-interpolation baseline for motion infilling (the CAE paper's "Linear interpolation" row)."""
from __future__ import annotations

import numpy as np

__all__ = ["linear_fill"]


def linear_fill(x, mask) -> np.ndarray:
    """Fill every row's missing entries by linear interpolation in time between its nearest known entries
    (held constant before the first / after the last known entry); a row with nothing known gets 0 (the
    training mean of normalised features).

    x: (..., D, T) (e.g. normalised clip images); mask: broadcastable to x, 1 = known, 0 = missing.
    Returns (..., D, T) float32.
    """
    x = np.asarray(x, np.float32)
    m = np.broadcast_to(np.asarray(mask) > 0.5, x.shape)
    flat, fm = x.reshape(-1, x.shape[-1]), m.reshape(-1, x.shape[-1])
    out = flat.copy()
    t = np.arange(x.shape[-1])
    for i in np.flatnonzero(~fm.all(axis=1)):
        k = fm[i]
        out[i] = np.interp(t, t[k], flat[i, k]) if k.any() else 0.0
    return out.reshape(x.shape)
