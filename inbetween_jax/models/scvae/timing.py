"""The sampled mode's timing variants: the same in-between replayed earlier or later, whole or per body part.

Beyond the paper; inference only (``model.timing_spread``, ``model.timing_parts``).  Two keyframes do not say when
the motion between them happens, nor whether the arms move before the legs.  Sample s >= 1 of the S-CVAE's
sampled mode is replayed on a warped clock ``u(t) = t + a sin(pi t) / pi`` (t in [0, 1] from one keyframe to the
other; monotone for ``|a| < 1``; ``a > 0`` moves the motion earlier).  With ``timing_parts`` each body part has
its own amplitude: half the samples are retimed whole, the other half move the arms against the legs or one side
against the other (:func:`part_amplitudes`).  Sample 0 is never changed, and neither are the keyframes.
The spread may differ per keyframe pair: ``model.timing_spread_fallback`` widens it where the out-of-distribution
gate falls back to Slerp (:func:`~.bank.sample_timing_spread`).

NumPy only; shapes: S samples, B keyframe pairs, L frames strictly between the keyframes, J joints.
"""
from __future__ import annotations

import numpy as np

from inbetween_jax.geometry.kinematics import forward_kinematics, local_positions
from inbetween_jax.geometry.quaternion import quat_align, quat_slerp

__all__ = ["PARTS", "timing_amplitudes", "part_amplitudes", "body_parts", "retimed"]

PARTS = ("torso", "left arm", "right arm", "left leg", "right leg")     # body_parts' labels 0..4
# the part-wise samples' signs per part (torso, left arm, right arm, left leg, right leg), in the order used
PART_PATTERNS = np.array([[0, 1, 1, -1, -1], [0, -1, -1, 1, 1], [0, 1, -1, 0, 0], [0, -1, 1, 0, 0],
                          [0, 0, 0, 1, -1], [0, 0, 0, -1, 1]], np.float64)


def timing_amplitudes(num_samples: int, spread: float) -> np.ndarray:
    """(S,) whole-body warp amplitudes: 0 for sample 0, then +-spread/m, +-2 spread/m, ..., alternating
    (m = ceil((S - 1) / 2)), so the samples cover early and late timings evenly; ``spread`` is capped at 0.95 (the
    warp stays monotone below 1)."""
    spread = min(float(spread), 0.95)
    s = np.arange(num_samples)
    m = max(int(np.ceil((num_samples - 1) / 2)), 1)
    return np.where(s == 0, 0.0, np.where(s % 2 == 1, 1.0, -1.0) * np.ceil(s / 2) * spread / m)


def part_amplitudes(num_samples: int, spread: float, parts: bool = True) -> np.ndarray:
    """(S, len(PARTS)) warp amplitudes per sample and body part.  Without ``parts`` every part follows
    :func:`timing_amplitudes`.  With it, samples 1..floor((S - 1) / 2) are retimed whole (``timing_amplitudes``
    over those samples) and the other ceil((S - 1) / 2) take :data:`PART_PATTERNS` in turn (arms earlier than the
    legs, later, the left arm against the right, the legs against each other), each at amplitude ``spread``
    (later rounds of the patterns at ``spread`` times the round's share, so no two samples are alike)."""
    spread = min(float(spread), 0.95)
    if not parts:
        return np.repeat(timing_amplitudes(num_samples, spread)[:, None], len(PARTS), 1)
    n_whole = max(num_samples - 1, 0) // 2
    out = np.zeros((num_samples, len(PARTS)))
    out[1:n_whole + 1] = timing_amplitudes(n_whole + 1, spread)[1:, None]
    n_part = num_samples - 1 - n_whole
    rounds = max(int(np.ceil(n_part / len(PART_PATTERNS))), 1)
    for i in range(n_part):
        rnd, pat = divmod(i, len(PART_PATTERNS))
        out[n_whole + 1 + i] = PART_PATTERNS[pat] * spread * (rounds - rnd) / rounds
    return out


def body_parts(skeleton) -> np.ndarray:
    """(J,) the body part (index into :data:`PARTS`) of every joint: the subtrees hanging off the spine (the path
    from the root to the head or neck joint) are legs where they hold a foot joint, arms otherwise, sided by
    their rest position along the left foot's side; the spine, the head (with whatever hangs off it or the neck)
    and any single-joint subtree are the torso.
    A rig without named feet and head is all torso (whole-body timing only)."""
    parents = np.asarray(skeleton.parents)
    j = len(parents)
    parts = np.zeros(j, np.int64)
    try:
        la, _, ra, _ = skeleton.foot_joints()
    except KeyError:
        return parts
    lower = [n.lower() for n in skeleton.names]
    head = lower.index("head") if "head" in lower else lower.index("neck") if "neck" in lower else None
    if head is None:
        return parts
    offsets = np.asarray(skeleton.offsets, np.float64)
    rest = forward_kinematics(np.tile([1.0, 0.0, 0.0, 0.0], (j, 1)), local_positions(np.zeros(3), offsets),
                              skeleton.parents)[1]                                       # the rest pose
    left = rest[la] - rest[ra]
    spine = set()
    i = head
    while i >= 0:
        spine.add(i)
        i = parents[i]

    def subtree(root):
        out, todo = [], [root]
        while todo:
            k = todo.pop()
            out.append(k)
            todo += skeleton.children(k)
        return out
    for s in sorted(spine):
        if lower[s] in ("head", "neck"):                       # eyes, jaw: the head's
            continue
        for c in (c for c in skeleton.children(s) if c not in spine):
            members = subtree(c)
            side_left = float(np.mean(rest[members], 0) @ left - rest[s] @ left) > 0
            if la in members or ra in members:
                parts[members] = 3 if la in members else 4
            elif len(members) > 1:
                parts[members] = 1 if side_left else 2
    return parts


def retimed(key_q, key_r, tgt_q, tgt_r, q, r, spread, parts=None, ease=None):
    """Sample s of q (S, B, L, J, 4), r (S, B, L, 3) -- the frames strictly between keyframes key (B, J, 4) /
    (B, 3) and tgt -- replayed along the warped time of :func:`part_amplitudes` (``parts`` (J,) :func:`body_parts`
    labels: each joint on its part's clock, the root on the torso's; None: the whole body on
    :func:`timing_amplitudes`' clock), slerping / lerping between the frames it falls between.  ``spread``: a
    number, or (B,) one per keyframe pair.  ``ease`` (S, B), optional: a second harmonic ``e sin(2 pi t) / (2 pi)``
    added to the clock (e < 0: slower near both keyframes, faster between), held to what keeps the clock monotone
    (|a| + |e| <= 0.95).  Sample 0 is unchanged.  Returns float64 arrays of q's and r's shapes."""
    q, r = np.array(q, np.float64), np.array(r, np.float64)
    n_s, n_b, length, n_j = q.shape[:4]
    joint_part = np.zeros(n_j, np.int64) if parts is None else np.asarray(parts, np.int64)
    spreads = np.minimum(np.broadcast_to(np.asarray(spread, np.float64), (n_b,)), 0.95)
    amps = part_amplitudes(n_s, 0.5, parts is not None)[:, joint_part] / 0.5      # (S, J) per unit spread (linear)
    t = np.arange(1, length + 1) / (length + 1)
    for s in range(1, n_s):
        fq = np.concatenate([np.asarray(key_q, np.float64)[:, None], q[s], np.asarray(tgt_q, np.float64)[:, None]], 1)
        fr = np.concatenate([np.asarray(key_r, np.float64)[:, None], r[s], np.asarray(tgt_r, np.float64)[:, None]], 1)
        a = spreads[:, None, None] * amps[s][None, None]                                     # (B, 1, J)
        tau = t[None, :, None] + a * np.sin(np.pi * t)[None, :, None] / np.pi                      # (B, L, J)
        if ease is not None:
            room = np.maximum(0.95 - np.abs(a), 0.0)
            e = np.clip(np.asarray(ease, np.float64)[s][:, None, None], -room, room)
            tau = tau + e * np.sin(2 * np.pi * t)[None, :, None] / (2 * np.pi)
        tau = tau * (length + 1)
        lo = np.clip(np.floor(tau).astype(int), 0, length)
        frac = tau - lo
        q0 = np.take_along_axis(fq, lo[..., None], 1)
        q1 = np.take_along_axis(fq, lo[..., None] + 1, 1)
        q[s] = quat_slerp(q0, quat_align(q1, q0), frac)
        lr, fr_ = lo[:, :, :1], frac[:, :, :1]                                             # the root: joint 0's clock
        r0 = np.take_along_axis(fr, lr, 1)
        r[s] = r0 + fr_ * (np.take_along_axis(fr, lr + 1, 1) - r0)
    return q, r
