"""The interaction model's out-of-distribution gate (:mod:`inbetween_jax.models.ood`): a score per window and
the blend of the two characters' in-between toward per-character interpolation as the score rises.

The score is a :class:`~inbetween_jax.models.ood.SpeedScore` of the context's motion: the mean joint speed of
both characters at the last context frame (cm per frame).  On the validation take the network (with its bank)
loses to interpolation where the dancers barely move, as the S-CVAE does where the keyframes imply little travel;
a k-NN distance of the window (the motion bank's match features) to the training takes did not predict where it
loses (Spearman 0.02, docs/results/gate.md).  ``ood.npz`` in the run (or shipped) folder holds scorer and gate;
``model.ood_gate`` switches the blend on.  Only a known gap is gated (``inbetween infill`` always knows it; the
bench's guessed-gap rows are not gated).
"""
from __future__ import annotations

import numpy as np

__all__ = ["window_context", "interpolation_base", "gate_blend", "gate_rollouts"]


def window_context(context) -> np.ndarray:
    """(B, 1) contexts: the mean joint speed (cm per frame) of both characters between the last two frames of
    context (B, 2, >= 2, J, >= 3) (key space, positions in metres)."""
    c = np.asarray(context, np.float64)[..., :3]
    speed = np.linalg.norm(c[:, :, -1] - c[:, :, -2], axis=-1).mean((1, 2)) * 100.0
    return speed[:, None]


def interpolation_base(context, keypose, frames: int) -> np.ndarray:
    """Per-character interpolation from the last context frame to the keypose: (B, 2, frames, J, 9)."""
    from inbetween_jax.baselines import two_character_interpolation
    return np.asarray(two_character_interpolation(np.asarray(context)[:, :, -1], keypose, frames), np.float32)


def gate_blend(rollouts, base, weight) -> np.ndarray:
    """Rollouts (S, B, 2, F, J, 9) moved toward the base (B, 2, n, J, 9) over their first n frames, the learned
    part kept at ``weight`` (B,); forward / up vectors are blended and re-normalised."""
    out = np.array(rollouts, np.float32)
    n = min(base.shape[2], out.shape[3])
    w = np.asarray(weight, np.float32)[None, :, None, None, None, None]
    mix = base[None, :, :, :n] + w * (out[:, :, :, :n] - base[None, :, :, :n])
    for lo in (3, 6):                                       # forward, up: unit vectors again
        v = mix[..., lo:lo + 3]
        mix[..., lo:lo + 3] = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-6)
    out[:, :, :, :n] = mix
    return out


def gate_rollouts(gate, rollouts, context, keypose, gaps):
    """The gate ((scorer, Gate)) on rollouts (S, B, 2, F, J, 9) of B windows with contexts (B, 2, n_input, J, 9),
    keyposes (B, 2, J, 9) and gaps (B,) (all one length).  Returns (rollouts, score (B,), weight (B,))."""
    gaps = np.asarray(gaps).astype(int)
    if len(np.unique(gaps)) != 1:
        raise ValueError("gate_rollouts: windows of one gap length at a time")
    score = gate[0].score(window_context(context))
    weight = gate[1].weight(score)
    base = interpolation_base(context, keypose, int(gaps[0]))
    return gate_blend(rollouts, base, weight), score, weight
