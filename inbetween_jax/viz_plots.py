"""Error-over-time plots of transitions (matplotlib, Agg), with the conventions of :mod:`inbetween_jax.viz`: inputs
checked first (``ValueError``, one line, nothing written), an atomic write, ``path`` returned."""
from __future__ import annotations

import os
from typing import Mapping, Optional

import matplotlib

matplotlib.use("Agg")  # no screen: never pick an interactive backend from the environment
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from inbetween_jax.viz_frames import save_atomic  # noqa: E402

__all__ = ["plot_error_over_time"]


def _check_curve(values, name: str, length: Optional[int] = None) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 1 or arr.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array, got shape {arr.shape}")
    if length is not None and arr.shape[0] != length:
        raise ValueError(f"{name} has {arr.shape[0]} values but times has {length}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains a non-finite value at index {int(np.argmax(~np.isfinite(arr)))}")
    return arr


def plot_error_over_time(times, mean, lo, hi, path, label: str, baseline: Optional[Mapping] = None,
                         ylabel: str = "L2P error", *, xlabel: str = "frame of the transition",
                         title: Optional[str] = None, dpi: int = 100) -> str:
    """Error along the transition with a shaded diversity band, as a PNG.

    times, mean, lo, hi: (T,) arrays; the band spans lo..hi (min..max, or mean -/+ std, over
    samples) and needs lo <= hi. baseline: optional {label: (T,) curve}, drawn dashed.
    Returns ``path``.
    """
    x = _check_curve(times, "times")
    m, l_, h = (_check_curve(v, n, len(x)) for v, n in ((mean, "mean"), (lo, "lo"), (hi, "hi")))
    if np.any(l_ > h):
        raise ValueError(f"lo > hi at index {int(np.argmax(l_ > h))}")
    curves = {str(k): _check_curve(v, f"baseline {k!r}", len(x)) for k, v in (baseline or {}).items()}
    fig = plt.figure(figsize=(5.0, 3.2), dpi=dpi, facecolor="white")
    try:
        ax = fig.add_subplot()
        line = ax.plot(x, m, lw=2.0, label=label)[0]
        ax.fill_between(x, l_, h, color=line.get_color(), alpha=0.25, lw=0.0, label=f"{label} (range)")
        for name, curve in curves.items():
            ax.plot(x, curve, ls="--", lw=1.5, label=name)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        if title:
            ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, frameon=False)
        fig.tight_layout()
        save_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=dpi, facecolor="white"), ".png")
    finally:
        plt.close(fig)
    return os.fspath(path)
