"""The network's fill meets each keyframe at the capture's speed (``model.net_edge_fade``, an inference switch;
not in the paper).

The CAE's network fills a gap with its own motion, and where the gate keeps it (walks, runs) that motion leaves
and reaches the keyframes at another speed than the capture's: on the validation subjects a joint's step changed
by 0.97 cm per frame across the keyframes of those gaps, twice the capture's own 0.46 (docs/results/gate.md,
2026-12-07, edge fade).  Per whole gap ``[a, b)`` and body row, with the known frames ``p = a - 1`` and ``q = b``
(``L1 = q - p``, ``s = (t - p) / L1``), the difference between the capture's velocity at each edge (the one-sided
second-order difference, first-order where one more known frame only) and the fill's first / last step is added
as its own Hermite term faded from that edge::

    y(t) += L1 (h10(s) (v_p - (y_{p+1} - x_p)) exp(-k (t - p - 1)) + h11(s) (v_q - (x_q - y_{q-1})) exp(-k (q - 1 - t)))

so the first and last steps of the fill become about the capture's, and the network's fill is itself again within
about ``1 / k`` frames; the keyframes are untouched (both terms are 0 there).  An edge without the known frames
for a velocity is left as it is.
"""
from __future__ import annotations

import numpy as np

__all__ = ["match_edge_velocity"]


def _velocity(x, known, i: int, step: int):
    """The capture's velocity (per frame, in time order) at known frame ``i`` from the frames on the ``step`` side
    (-1: before, +1: after), or None when frame ``i + step`` is not known."""
    t_len = x.shape[-1]
    if not (0 <= i + step < t_len and known[i + step]):
        return None
    if 0 <= i + 2 * step < t_len and known[i + 2 * step]:
        return -step * (3 * x[:, i] - 4 * x[:, i + step] + x[:, i + 2 * step]) / 2
    return -step * (x[:, i] - x[:, i + step])


def match_edge_velocity(y, x_masked, mask, k: float, rows: slice) -> np.ndarray:
    """Fills y (N, D, T) with each whole gap's ``rows`` given the capture's edge velocities (module docstring),
    read from the known frames of ``x_masked`` (N, D, T; ``mask`` broadcastable, 1 = known); returns a new array.
    Frames that keep some entries (joint dropout) are not a gap."""
    from inbetween_jax.models.cae.masks import gap_ranges
    out = np.array(y, np.float32, copy=True)
    m = np.broadcast_to(np.asarray(mask, np.float32), out.shape)
    x = np.asarray(x_masked, np.float32)
    t_len = out.shape[-1]
    for i in range(len(out)):
        known = m[i].max(axis=0) > 0.5
        xi, yi = x[i, rows], out[i, rows]
        for a, b in gap_ranges(known.astype(np.float32)):
            if a == 0 or b == t_len:
                continue
            p, q = a - 1, b
            span = q - p
            t = np.arange(a, b)
            s = (t - p) / span
            h10, h11 = s ** 3 - 2 * s ** 2 + s, s ** 3 - s ** 2
            v0, v1 = _velocity(xi, known, p, -1), _velocity(xi, known, q, 1)
            add = np.zeros_like(yi[:, a:b])
            if v0 is not None:                      # the fill's first step against the capture's velocity
                add += span * (v0 - (yi[:, a] - xi[:, p]))[:, None] * (h10 * np.exp(-k * (t - p - 1)))[None]
            if v1 is not None:                      # ... and its last step
                add += span * (v1 - (xi[:, q] - yi[:, b - 1]))[:, None] * (h11 * np.exp(-k * (q - 1 - t)))[None]
            yi[:, a:b] += add
        out[i, rows] = yi
    return out
