"""The S-CVAE's fill inside a clip (``model.context_base``, inference only): where the frames beside the
keyframes are known (``inbetween infill`` on a file: the frame before the start keyframe, the frame after the
end keyframe), the samples' departure from Slerp / lerp is added onto the two-sided Hermite path through the
keyframes, which leaves the start and arrives at the end with the motion's own velocities
(:func:`~inbetween_jax.baselines.velocity_interpolation.velocity_offsets`, damped by ``model.context_damping``
per frame).  The network, trained from two keyframes as in the paper, never sees those velocities; Slerp ignores
them too.

    q = H_q * (S_q^-1 q_sample),      r = H_r + (r_sample - S_r)        (local quaternions, per joint)

with ``S`` Slerp / lerp and ``H`` the Hermite path.  A fill the gate sent back to Slerp becomes the Hermite path.
With only the frame before the start known, ``H`` has the start term only; with neither, ``H = S`` and nothing
changes.  Chosen on the validation subjects (``experiments/scvae_context_base.py``; docs/results/gate.md).
"""
from __future__ import annotations

import numpy as np

from inbetween_jax.baselines.velocity_interpolation import velocity_offsets
from inbetween_jax.geometry import quat_align, quat_conj, quat_mul, quat_normalize

__all__ = ["context_offsets", "limit_neighbour", "neighbours", "known_sides", "onto_context", "context_kind",
           "in_clip", "clip_keyframes", "BEFORE", "AFTER", "HERMITE_NAME", "IN_CLIP_NAME"]

HERMITE_NAME = "Hermite through the frames beside the keyframes"      # bench rows (models/scvae/bench.py)
IN_CLIP_NAME = "S-CVAE inside a clip (onto that Hermite path)"


def limit_neighbour(q_key, r_key, q_nb, r_nb, max_turn: float, max_step: float, q_nb2=None, r_nb2=None):
    """The velocity the Hermite path continues on one side of a keyframe, made robust: returned as an effective
    neighbouring frame (q (B, J, 4), r (B, 3), float64) one step from the keyframe (q_key, r_key).

    Per joint the step is the smaller turn of the one-frame step to the neighbour (q_nb, r_nb) and half the
    two-frame step to the next one (q_nb2, r_nb2, optional), so a single glitched frame on that side does not
    count; then no joint turns more than ``max_turn`` radians and the root moves at most ``max_step`` (file
    units; 0: no cap)."""
    from inbetween_jax.geometry import quat_from_axis_angle, quat_to_axis_angle
    q_key, r_key = np.asarray(q_key, np.float64), np.asarray(r_key, np.float64)

    def turn(q, scale):               # rotation vector from the keyframe to q, times scale
        axis, angle = quat_to_axis_angle(quat_mul(quat_conj(q_key), quat_align(np.asarray(q, np.float64), q_key)))
        return axis * (scale * angle)[..., None]

    w, d = turn(q_nb, 1.0), np.asarray(r_nb, np.float64) - r_key
    if q_nb2 is not None:
        w2, d2 = turn(q_nb2, 0.5), 0.5 * (np.asarray(r_nb2, np.float64) - r_key)
        w = np.where(np.linalg.norm(w2, axis=-1, keepdims=True) < np.linalg.norm(w, axis=-1, keepdims=True), w2, w)
        d = np.where(np.linalg.norm(d2, axis=-1, keepdims=True) < np.linalg.norm(d, axis=-1, keepdims=True), d2, d)
    angle = np.linalg.norm(w, axis=-1)
    if max_turn > 0:
        w = w * (np.minimum(angle, max_turn) / np.maximum(angle, 1e-12))[..., None]
        angle = np.minimum(angle, max_turn)
    if max_step > 0:
        d = d * np.minimum(1.0, max_step / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12))
    q = quat_normalize(quat_mul(q_key, quat_from_axis_angle(w / np.maximum(angle, 1e-12)[..., None], angle)))
    return q, r_key + d


def neighbours(cfg, skeleton, q0, r0, q1, r1, before=None, after=None) -> tuple:
    """``(qp, rp, qn, rn)`` for :func:`context_offsets`: the frame before the start keyframe and the frame after
    the end keyframe as :func:`limit_neighbour` makes them, from ``before`` = (qp, rp, qp2, rp2) (the two frames
    before the start, nearest first) and ``after`` = (qn, rn, qn2, rn2); a side without both frames is not used
    (None).  Caps: ``cfg.context_max_turn`` radians and ``cfg.context_max_step`` leg lengths of ``skeleton`` per
    frame (cfg: ModelConfig)."""
    from inbetween_jax.data.features import leg_length
    step = cfg.context_max_step * leg_length(skeleton)
    out = []
    for key_q, key_r, side in ((q0, r0, before), (q1, r1, after)):
        if side is None or any(x is None for x in side):
            out += [None, None]
        else:
            out += list(limit_neighbour(key_q, key_r, side[0], side[1], cfg.context_max_turn, step, side[2], side[3]))
    return tuple(out)


def context_offsets(q0, r0, q1, r1, n_frames: int, damping: float, qp=None, rp=None, qn=None, rn=None):
    """The Hermite path's offsets from Slerp / lerp at the ``n_frames`` frames strictly between B keyframe pairs:
    (dq (B, n, J, 4) to right-multiply onto Slerp, dr (B, n, 3) to add to the lerp), float64.

    q0 / q1 (B, J, 4) local quaternions, r0 / r1 (B, 3) roots of the keyframes; qp / rp the frame before the start
    keyframe, qn / rn the frame after the end keyframe (each pair may be None)."""
    import jax.numpy as jnp
    def f32(x, ref=None):             # sign-aligned to ref first (None stays None)
        if x is None:
            return None
        x = np.asarray(x, np.float64)
        return jnp.asarray(x if ref is None else quat_align(x, ref), jnp.float32)

    q0 = np.asarray(q0, np.float64)
    q1 = quat_align(np.asarray(q1, np.float64), q0)
    dq, dr = velocity_offsets(f32(qp, q0), f32(q0), f32(q1), f32(rp), f32(r0), f32(r1), n_frames + 1, n_frames + 1,
                              damping, q_next=f32(qn, q1), r_next=f32(rn))
    return np.asarray(dq[:, 1:n_frames + 1], np.float64), np.asarray(dr[:, 1:n_frames + 1], np.float64)


def onto_context(q, r, slerp_q, slerp_r, dq, dr):
    """Samples q (S, B, L, J, 4), r (S, B, L, 3) moved from Slerp / lerp (slerp_q (B, L, J, 4), slerp_r (B, L, 3))
    onto the Hermite path ``Slerp * dq``, ``lerp + dr`` (:func:`context_offsets`), keeping their departure from
    Slerp / lerp.  Returns float64 arrays of q's and r's shapes."""
    q, r = np.asarray(q, np.float64), np.asarray(r, np.float64)
    sq = np.asarray(slerp_q, np.float64)[None]
    departure = quat_mul(quat_conj(sq), q)
    out = quat_mul(quat_mul(sq, np.asarray(dq, np.float64)[None]), departure)
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return out, r + np.asarray(dr, np.float64)[None]


BEFORE, AFTER = ("qp", "rp", "qp2", "rp2"), ("qn", "rn", "qn2", "rn2")   # the keys infill_between reads


def clip_keyframes(m, k0: int, k1: int, contacts=(None, None)) -> tuple:
    """``(start, end)`` keyframe dicts for a gap between frames ``k0`` and ``k1`` of motion ``m`` (a
    :class:`~inbetween_jax.data.bvh.Motion`), with the two frames on each side where the motion holds them
    (:data:`BEFORE` / :data:`AFTER`), as ``inbetween infill`` passes a gap inside a file to a ``context_base``
    model.  ``contacts``: the keyframes' contact labels (4,), zeros where None."""
    q, r = m.local_quats, m.root_pos
    start, end = ({"q": q[k], "r": r[k], "c": np.zeros(4) if c is None else c} for k, c in zip((k0, k1), contacts))
    for d, keys, (a, b) in ((start, BEFORE, (k0 - 1, k0 - 2)), (end, AFTER, (k1 + 1, k1 + 2))):
        if 0 <= min(a, b) and max(a, b) < m.num_frames:
            d.update(zip(keys, (q[a], r[a], q[b], r[b])))
    return start, end


def known_sides(start: dict, end: dict) -> tuple:
    """``(before, after)`` for :func:`neighbours` from keyframe dicts carrying :data:`BEFORE` / :data:`AFTER`
    (each side its four arrays with a batch axis of one, or None without both frames)."""
    def side(d, keys):
        return tuple(np.asarray(d[k], np.float64)[None] for k in keys) if all(k in d for k in keys) else None
    return side(start, BEFORE), side(end, AFTER)


def context_kind(start: dict, end: dict) -> str:
    """Which sides of the gap a fill continues the motion of: "both sides", "before the start", "after the end"
    or "none" (a side needs two frames: ``start`` carrying :data:`BEFORE`, ``end`` :data:`AFTER`)."""
    before, after = all(k in start for k in BEFORE), all(k in end for k in AFTER)
    return {(True, True): "both sides", (True, False): "before the start", (False, True): "after the end",
            (False, False): "none"}[(before, after)]


def in_clip(windows, n_past: int, n_trans: int, q, r, cfg, use_after: bool = True):
    """The bench's in-clip rows: samples q (S, B, L, J, 4), r (S, B, L, 3) of the transitions after frame
    ``n_past - 1`` of B windows moved onto the Hermite path through the frames before the start and after the end
    keyframe (two on each side, where the windows hold them; ``use_after`` False: the frames before the start
    only, as ``infill`` at a clip's end).  Returns (q, r, hermite_q (1, B, L, J, 4), hermite_r (1, B, L, 3)),
    float64: the moved samples and the Hermite path alone (cfg: ModelConfig, its ``context_*`` switches)."""
    from inbetween_jax.models.scvae.gate import slerp_base
    lq, rp = np.asarray(windows.local_quats, np.float64), np.asarray(windows.root_pos, np.float64)
    k0, k1 = n_past - 1, n_past + n_trans
    sq, sr = slerp_base(lq[:, k0], rp[:, k0], lq[:, k1], rp[:, k1], n_trans)
    keys = (lq[:, k0], rp[:, k0], lq[:, k1], rp[:, k1])
    before = (lq[:, k0 - 1], rp[:, k0 - 1], lq[:, k0 - 2], rp[:, k0 - 2]) if k0 >= 2 else None
    after = ((lq[:, k1 + 1], rp[:, k1 + 1], lq[:, k1 + 2], rp[:, k1 + 2]) if use_after and k1 + 2 < lq.shape[1]
             else None)
    nb = neighbours(cfg, windows.skeleton, *keys, before, after)
    dq, dr = context_offsets(*keys, n_trans, cfg.context_damping, *nb)
    mq, mr = onto_context(q, r, sq, sr, dq, dr)
    return mq, mr, quat_normalize(quat_mul(sq, dq))[None], (sr + dr)[None]
