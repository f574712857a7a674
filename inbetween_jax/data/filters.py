"""Temporal filters of motion signals (pure NumPy)."""
from __future__ import annotations

import numpy as np

__all__ = ["gaussian_lowpass"]


def gaussian_lowpass(x, sigma: float, axis: int, dtype=np.float32) -> np.ndarray:
    """``x`` filtered along ``axis`` by a normalised Gaussian of ``sigma`` frames, truncated at 3 sigma, the
    edge frames repeated beyond the ends; computed in float64, returned as ``dtype``."""
    r = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    x = np.moveaxis(np.asarray(x, np.float64), axis, -1)
    pad = np.concatenate([np.repeat(x[..., :1], r, -1), x, np.repeat(x[..., -1:], r, -1)], -1)
    out = sum(w * pad[..., i:i + x.shape[-1]] for i, w in enumerate(k))
    return np.moveaxis(out, -1, axis).astype(dtype)
