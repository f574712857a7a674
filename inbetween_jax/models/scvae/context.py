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
from inbetween_jax.geometry import quat_conj, quat_mul, quat_normalize

__all__ = ["context_offsets", "onto_context", "context_kind", "in_clip", "HERMITE_NAME", "IN_CLIP_NAME"]

HERMITE_NAME = "Hermite through the frames beside the keyframes"      # bench rows (models/scvae/bench.py)
IN_CLIP_NAME = "S-CVAE inside a clip (onto that Hermite path)"


def _aligned(q, ref):
    q = np.asarray(q, np.float64)
    return np.where(np.sum(q * ref, -1, keepdims=True) < 0, -q, q)


def context_offsets(q0, r0, q1, r1, n_frames: int, damping: float, qp=None, rp=None, qn=None, rn=None):
    """The Hermite path's offsets from Slerp / lerp at the ``n_frames`` frames strictly between B keyframe pairs:
    (dq (B, n, J, 4) to right-multiply onto Slerp, dr (B, n, 3) to add to the lerp), float64.

    q0 / q1 (B, J, 4) local quaternions, r0 / r1 (B, 3) roots of the keyframes; qp / rp the frame before the start
    keyframe, qn / rn the frame after the end keyframe (each pair may be None)."""
    import jax.numpy as jnp
    q0 = np.asarray(q0, np.float64)
    q1 = _aligned(q1, q0)
    f32 = lambda x: None if x is None else jnp.asarray(x, jnp.float32)  # noqa: E731
    dq, dr = velocity_offsets(f32(None if qp is None else _aligned(qp, q0)), f32(q0), f32(q1), f32(rp), f32(r0),
                              f32(r1), n_frames + 1, n_frames + 1, damping,
                              q_next=f32(None if qn is None else _aligned(qn, q1)), r_next=f32(rn))
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


def context_kind(start: dict, end: dict) -> str:
    """Which frames beside the keyframes a fill continues: "both sides", "before the start", "after the end" or
    "none" (``start`` may carry ``qp`` / ``rp``, ``end`` ``qn`` / ``rn``)."""
    before, after = "qp" in start and "rp" in start, "qn" in end and "rn" in end
    return {(True, True): "both sides", (True, False): "before the start", (False, True): "after the end",
            (False, False): "none"}[(before, after)]


def in_clip(windows, n_past: int, n_trans: int, q, r, damping: float):
    """The bench's in-clip rows: samples q (S, B, L, J, 4), r (S, B, L, 3) of the transitions after frame
    ``n_past - 1`` of B windows (needs ``n_past >= 2``) moved onto the Hermite path through frame ``n_past - 2``
    and frame ``n_past + n_trans + 1`` (where the windows hold it).  Returns (q, r, hermite_q (1, B, L, J, 4),
    hermite_r (1, B, L, 3)), float64: the moved samples and the Hermite path alone."""
    from inbetween_jax.models.scvae.gate import slerp_base
    lq, rp = np.asarray(windows.local_quats, np.float64), np.asarray(windows.root_pos, np.float64)
    k0, k1 = n_past - 1, n_past + n_trans
    after = k1 + 1 < lq.shape[1]
    sq, sr = slerp_base(lq[:, k0], rp[:, k0], lq[:, k1], rp[:, k1], n_trans)
    dq, dr = context_offsets(lq[:, k0], rp[:, k0], lq[:, k1], rp[:, k1], n_trans, damping, lq[:, k0 - 1],
                             rp[:, k0 - 1], lq[:, k1 + 1] if after else None, rp[:, k1 + 1] if after else None)
    mq, mr = onto_context(q, r, sq, sr, dq, dr)
    return mq, mr, quat_normalize(quat_mul(sq, dq))[None], (sr + dr)[None]
