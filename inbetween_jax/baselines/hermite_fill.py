"""Cubic Hermite fill baseline for motion infilling: like :func:`~inbetween_jax.baselines.linear_fill`, but each
gap is bridged by a cubic that also matches the velocities just outside it (not in the CAE paper).

Per row and per gap (a run of missing entries with known entries at ``p`` before and ``q`` after it), with
``L1 = q - p`` and ``s = (t - p) / L1``::

    fill(t) = h00(s) x_p + h01(s) x_q + L1 (h10(s) m_p + h11(s) m_q)      (the cubic Hermite basis)

The tangents are one-sided finite differences over known frames outside the gap, per frame: the second-order
``(3 x_p - 4 x_{p-1} + x_{p-2}) / 2`` (``(-3 x_q + 4 x_{q+1} - x_{q+2}) / 2`` after the gap) when two more
known frames lie on that side, the first-order ``x_p - x_{p-1}`` when only one does, else the secant slope
``d = (x_q - x_p) / L1`` (which gives the straight line).  With ``limit`` (default 3, Fritsch & Carlson 1980)
each tangent is limited against the secant: 0 where its sign differs from ``d`` (or ``d = 0``), magnitude at
most ``limit |d|``; this keeps the cubic from overshooting over long gaps, where an unlimited Hermite fill is
much worse than the straight line (docs/results/cae.md: 1.2x / 1.6x / 3.0x linear fill at 1 / 2 / 4 s).
Two fading forms keep the velocities at the gap's edges without the long swing (``k`` per frame):

* ``edge_fade`` k > 0 (with the limiter): the limited cubic plus, near each edge, the part of that edge's tangent
  the limiter cut, ``L1 (h10(s) (m_p - m'_p) exp(-k (t - p)) + h11(s) (m_q - m'_q) exp(-k (q - t)))`` (``m``
  unlimited, ``m'`` limited).  The limiter zeroes a tangent that points against the secant, so the limited fill
  stops a still-moving joint at the keyframe (a speed step); this gives the motion's own velocity back at the
  edge and is the limited cubic again within about ``1 / k`` frames.  The CAE's base
  (``model.base_edge_fade``, :func:`inbetween_jax.models.cae.gate.base_fill`).
* ``damping`` k > 0 (best without the limiter): each tangent's departure from the secant fades from its own edge,
  ``fill(t) = lerp(t) + L1 (h10(s) (m_p - d) exp(-k (t - p)) + h11(s) (m_q - d) exp(-k (q - t)))``, settling onto
  the straight line over a long gap (the edge motion moves the fill by at most ``|m - d| / (e k)``).  ``damping
  -> 0`` is the cubic itself (the Hermite basis is the line plus these two terms).

Entries before the first / after the last known entry of a row are held, a row with nothing known gets 0, and known
entries are returned unchanged -- all as :func:`linear_fill`.  A straight line is reproduced exactly (up to
rounding).

One implementation for NumPy and ``jax.numpy``: the CAE's residual form uses it inside its jitted apply
(``model.fill=hermite``, :mod:`inbetween_jax.models.cae.model`).
"""
from __future__ import annotations

import numpy as np

__all__ = ["hermite_fill"]


def _is_jax(x) -> bool:
    return type(x).__module__.startswith(("jax", "jaxlib"))


def hermite_fill(x, mask, limit: float | None = 3.0, order: int = 2, edge_fade: float = 0.0,
                 damping: float = 0.0):
    """Cubic Hermite fill of every row's missing entries (see the module docstring).

    x: (..., D, T) (e.g. normalised clip images; only the known entries are read); mask: broadcastable to x,
    1 = known, 0 = missing; limit: tangent limiter factor (None: no limiter, the plain Hermite cubic);
    order: 2 (second-order one-sided differences where two known frames exist, else first-order) or 1
    (first-order only); edge_fade / damping: per frame, the fading forms of the module docstring (0: off).
    Returns (..., D, T) float32, a NumPy array for NumPy input and a jax array for jax input (traceable under
    ``jax.jit``).
    """
    if _is_jax(x) or _is_jax(mask):
        import jax
        import jax.numpy as xp
        cummax = lambda a: jax.lax.cummax(a, axis=a.ndim - 1)                      # noqa: E731
        cummin_rev = lambda a: jax.lax.cummin(a, axis=a.ndim - 1, reverse=True)     # noqa: E731
    else:
        xp = np
        cummax = lambda a: np.maximum.accumulate(a, axis=-1)                         # noqa: E731
        cummin_rev = lambda a: np.flip(np.minimum.accumulate(np.flip(a, -1), axis=-1), -1)  # noqa: E731
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2, not {order!r}")
    x = xp.asarray(x, xp.float32)
    known = xp.broadcast_to(xp.asarray(mask) > 0.5, x.shape)
    t_len = x.shape[-1]
    t = xp.arange(t_len)
    prev = cummax(xp.where(known, t, -1))               # last known index <= t
    nxt = cummin_rev(xp.where(known, t, t_len))         # first known index >= t
    has_prev, has_next = prev >= 0, nxt < t_len

    def at(idx):   # x and known at idx (clipped), idx out of range: not known
        i = xp.clip(idx, 0, t_len - 1)
        ok = (idx >= 0) & (idx < t_len)
        return xp.take_along_axis(x, i, axis=-1), ok & xp.take_along_axis(known, i, axis=-1)

    xp0, _ = at(prev)
    xq0, _ = at(nxt)
    span = xp.maximum(nxt - prev, 1).astype(xp.float32)
    d = (xq0 - xp0) / span                              # secant slope per frame
    xp1, kp1 = at(prev - 1)
    xq1, kq1 = at(nxt + 1)
    m0 = xp.where(kp1, xp0 - xp1, d)
    m1 = xp.where(kq1, xq1 - xq0, d)
    if order == 2:
        xp2, kp2 = at(prev - 2)
        xq2, kq2 = at(nxt + 2)
        m0 = xp.where(kp1 & kp2, (3.0 * xp0 - 4.0 * xp1 + xp2) / 2.0, m0)
        m1 = xp.where(kq1 & kq2, (-3.0 * xq0 + 4.0 * xq1 - xq2) / 2.0, m1)
    raw0, raw1 = m0, m1
    if limit is not None:
        cap = float(limit) * xp.abs(d)
        m0 = xp.where(m0 * d > 0, xp.sign(m0) * xp.minimum(xp.abs(m0), cap), 0.0)
        m1 = xp.where(m1 * d > 0, xp.sign(m1) * xp.minimum(xp.abs(m1), cap), 0.0)
    s = ((t - prev) / span).astype(xp.float32)
    s2, s3 = s * s, s * s * s
    h00, h01 = 2.0 * s3 - 3.0 * s2 + 1.0, -2.0 * s3 + 3.0 * s2
    h10, h11 = s3 - 2.0 * s2 + s, s3 - s2

    def faded(k, c0, c1):       # the tangent parts c0 / c1, each faded by exp(-k frames) from its own edge
        return span * (h10 * c0 * xp.exp(-k * (t - prev)) + h11 * c1 * xp.exp(-k * (nxt - t))).astype(xp.float32)
    if damping:
        inner = (1.0 - s) * xp0 + s * xq0 + faded(float(damping), m0 - d, m1 - d)
    else:
        inner = h00 * xp0 + h01 * xq0 + span * (h10 * m0 + h11 * m1)
    if edge_fade:
        inner = inner + faded(float(edge_fade), raw0 - m0, raw1 - m1)
    filled = xp.where(has_prev & has_next, inner, xp.where(has_prev, xp0, xp.where(has_next, xq0, 0.0)))
    return xp.where(known, x, filled).astype(xp.float32)
