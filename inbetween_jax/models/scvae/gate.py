"""The S-CVAE's out-of-distribution gate (:mod:`inbetween_jax.models.ood`): a score per keyframe pair and the
blend of the samples toward Slerp / lerp as the score rises.

Context of a transition: the two keyframes turned into the space the S-CVAE samples in
(:func:`inbetween_jax.data.windows.canonicalize`: centred in XZ between them, the start facing +X), as FK joint
positions of both poses (2 J 3 numbers, so the root's displacement between the keyframes is in it) plus the
number of frames between them / 30.  The bank holds the same for keyframe pairs of the training windows, at
random lengths.  ``ood.npz`` in the run (or shipped) folder holds bank and gate; ``model.ood_gate`` switches the
blend on.

Inside a clip (``model.context_base``: the frames beside the keyframes known) the fill's base is the Hermite path
through them, much closer to the motion than Slerp.  There the gate reads the same score with its own thresholds
(:func:`context_gate`), calibrated against that path (:func:`~.calibrate.in_clip_records`).
"""
from __future__ import annotations

import numpy as np

__all__ = ["keyframe_context", "training_contexts", "gate_blend", "slerp_base", "gate_pairs", "gate_windows",
           "CONTEXT_GATE_KEYS", "context_gate"]

CONTEXT_GATE_KEYS = ("context_gate_lo", "context_gate_hi")   # ood.npz: the thresholds used inside a clip


def keyframe_context(q0, r0, q1, r1, n_frames, skeleton, forward_axis) -> np.ndarray:
    """(B, 2 J 3 + 1) contexts of B keyframe pairs: q0 / q1 (B, J, 4) local quaternions, r0 / r1 (B, 3) root
    positions, n_frames (B,) or a number: frames generated between them."""
    from inbetween_jax.data.windows import canonicalize
    from inbetween_jax.geometry import forward_kinematics, local_positions
    q = np.stack([np.asarray(q0, np.float64), np.asarray(q1, np.float64)], 1)
    r = np.stack([np.asarray(r0, np.float64), np.asarray(r1, np.float64)], 1)
    cq, cr = canonicalize(q, r, skeleton, 1, np.asarray(forward_axis, np.float64))
    _, gp = forward_kinematics(cq, local_positions(cr, skeleton.offsets), skeleton.parents)     # (B, 2, J, 3)
    n = np.broadcast_to(np.asarray(n_frames, np.float64), (len(q),))
    return np.concatenate([gp.reshape(len(q), -1), n[:, None] / 30.0], axis=1)


def training_contexts(windows, forward_axis, lengths=(5, 50), per_window: int = 2, seed: int = 0) -> np.ndarray:
    """Contexts of ``per_window`` keyframe pairs per training window: a random start frame and a random length
    in ``lengths`` (inclusive, capped by the window)."""
    rng = np.random.default_rng(seed)
    t = windows.window
    out = []
    for _ in range(per_window):
        n = rng.integers(lengths[0], min(lengths[1], t - 2) + 1, len(windows))
        k0 = (rng.random(len(windows)) * (t - n - 1)).astype(int)
        k1 = k0 + n + 1
        i = np.arange(len(windows))
        out.append(keyframe_context(windows.local_quats[i, k0], windows.root_pos[i, k0], windows.local_quats[i, k1],
                                    windows.root_pos[i, k1], n, windows.skeleton, forward_axis))
    return np.concatenate(out)


def training_bank(source: str, split: str, forward_axis):
    """The k-NN :class:`~inbetween_jax.models.ood.ContextBank` of a training split's keyframe contexts
    (:func:`training_contexts` of its 60-frame windows, every 20 frames), as ``calibrate-gate --kind knn`` uses."""
    from inbetween_jax.data import load_dataset
    from inbetween_jax.models.ood import build_bank
    return build_bank(training_contexts(load_dataset(source, split, window=60, offset=20), forward_axis))


def slerp_base(q0, r0, q1, r1, n_frames: int):
    """Slerp / lerp between keyframes: q (B, n, J, 4), r (B, n, 3) for the n frames strictly between them."""
    from inbetween_jax.geometry.quaternion import quat_align, quat_slerp
    w = (np.arange(1, n_frames + 1) / (n_frames + 1))
    q0, q1 = np.asarray(q0, np.float64), np.asarray(q1, np.float64)
    q1 = quat_align(q1, q0)
    q = quat_slerp(q0[:, None], q1[:, None], w[None, :, None])
    r = np.asarray(r0, np.float64)[:, None] + w[None, :, None] * (np.asarray(r1, np.float64) - r0)[:, None]
    return q, r


def gate_blend(q, r, base_q, base_r, weight):
    """Samples q (S, B, L, J, 4), r (S, B, L, 3) moved toward the base (B, L, J, 4) / (B, L, 3) with the learned
    fill kept at ``weight`` (B,) (1: the samples, 0: the base)."""
    from inbetween_jax.models.scvae.bank import blend
    a = 1.0 - np.asarray(weight, np.float64)[:, None, None]
    return blend(q, r, base_q, base_r, a)


def gate_pairs(gate, q0, r0, q1, r1, skeleton, forward_axis, q, r):
    """The gate ((scorer, Gate)) on samples q (S, B, L, J, 4), r (S, B, L, 3) of the L frames between B keyframe
    pairs q0 / q1 (B, J, 4), r0 / r1 (B, 3).  Returns (q, r, score (B,), weight (B,))."""
    n = np.shape(q)[2]
    a = (q0, r0, q1, r1)
    score = gate[0].score(keyframe_context(*a, n, skeleton, forward_axis))
    weight = gate[1].weight(score)
    return (*gate_blend(q, r, *slerp_base(*a, n), weight), score, weight)


def gate_windows(gate, windows, k0: int, k1: int, q, r, forward_axis=None):
    """:func:`gate_pairs` for the transitions between frames k0 and k1 of B windows."""
    fa = windows.skeleton.forward_axis() if forward_axis is None else forward_axis
    return gate_pairs(gate, windows.local_quats[:, k0], windows.root_pos[:, k0], windows.local_quats[:, k1],
                      windows.root_pos[:, k1], windows.skeleton, fa, q, r)


def context_gate(run_dir: str):
    """The :class:`~inbetween_jax.models.ood.Gate` of fills inside a clip, from ``run_dir/ood.npz``'s
    :data:`CONTEXT_GATE_KEYS`, or None when it holds none (a gate calibrated before 2026-12-06)."""
    from inbetween_jax.models.ood import Gate, optional_gate_arrays
    a = optional_gate_arrays(run_dir, "context_gate_", CONTEXT_GATE_KEYS)
    return None if a is None else Gate(float(a[CONTEXT_GATE_KEYS[0]]), float(a[CONTEXT_GATE_KEYS[1]]))
