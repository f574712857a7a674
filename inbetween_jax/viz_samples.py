"""N samples of one in-between side by side: a contact sheet whose every pose slot overlays the samples' poses
of that frame, one colour per sample (``inbetween infill --samples N --preview`` writes ``samples_sheet.png``).

Conventions as :mod:`inbetween_jax.viz`: positions in cm, Y up, a side view with the overall motion going left
to right, inputs checked first (``ValueError``, one line, nothing written), an atomic write.
"""
from __future__ import annotations

import os
from typing import Optional, Sequence

import numpy as np

from inbetween_jax.viz import (KEY_COLOR, _check_keyframes, _check_positions, _heading, _segments, _side_view, plt,
                               save_atomic, sheet_canvas, sheet_frames)

__all__ = ["samples_sheet"]

MAX_SAMPLES_DRAWN = 20


def samples_sheet(samples, parents, path, every: int = 5, keyframes: Sequence[int] = (), title: Optional[str] = None,
                  *, height: float = 2.5, dpi: int = 100, max_poses: int = 24) -> str:
    """Every ``every``-th frame (plus the keyframes) of all samples, overlaid per frame, as a PNG.

    samples: (N, T, J, 3) global positions of N samples of the same frames (N <= 20).  Each frame's slot sits
    where the samples' mean root is along the motion (evenly spread if slots would overlap); each sample's pose
    is drawn relative to that mean, so where the samples differ the figures fan out.  Keyframes are drawn black
    once (the samples share them).  Returns ``path``."""
    pos = np.asarray(samples, np.float64)
    if pos.ndim != 4 or not 1 <= pos.shape[0] <= MAX_SAMPLES_DRAWN:
        raise ValueError(f"samples must be (N, T, J, 3) with 1 <= N <= {MAX_SAMPLES_DRAWN}, got shape {pos.shape}")
    for s in pos:
        _check_positions(s, parents)
    par = tuple(int(p) for p in parents)
    n, t = pos.shape[:2]
    if int(every) < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    plan = sheet_frames(t, int(every), _check_keyframes(keyframes, t), max_poses)
    frames, keys = plan.frames, set(plan.keyframes)
    u = _heading(pos.mean(0)[:, 0, [0, 2]])
    xy = _side_view(pos[:, frames], u)                               # (N, F, J, 2)
    centre = xy[:, :, 0, 0].mean(0)                                  # (F,) the samples' mean root
    width = max(float(np.ptp(xy[..., 0] - centre[None, :, None], axis=2).max()), 20.0)
    slots = centre.copy()
    if len(frames) > 1 and np.diff(slots).min() < 0.9 * width:
        slots = np.arange(len(frames)) * 1.15 * width
    xy[..., 0] += (slots - centre)[None, :, None]
    colours = plt.get_cmap("tab10" if n <= 10 else "tab20")(np.arange(n) % (10 if n <= 10 else 20))
    fig, ax, ymin = sheet_canvas(xy, width, height, dpi, bool(title))
    try:
        from matplotlib.collections import LineCollection
        for f, frame in enumerate(frames):
            drawn = [0] if frame in keys else range(n)
            for i in drawn:
                colour = KEY_COLOR if frame in keys else colours[i]
                ax.add_collection(LineCollection(_segments(xy[i, f], par), colors=[colour], linewidths=1.2,
                                                 alpha=1.0 if frame in keys else 0.8), autolim=False)
            ax.text(slots[f], ymin + 1.0, str(frame), ha="center", va="bottom", fontsize=7,
                    color=KEY_COLOR if frame in keys else "#666666")
        label = " ".join(x for x in (title, plan.note) if x)
        if label:
            fig.suptitle(label, fontsize=9, y=0.99, va="top")
        save_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=dpi, facecolor="white"), ".png")
    finally:
        plt.close(fig)
    return os.fspath(path)
