"""The interaction model's out-of-distribution gate (:mod:`inbetween_jax.models.ood`): a score per window and
the blend of the two characters' in-between toward per-character interpolation as the score rises.

The score is a :class:`~inbetween_jax.models.ood.SpeedScore` of the context's motion: the mean joint speed of
both characters at the last context frame (cm per frame).  On the validation take the network (with its bank)
loses to interpolation where the dancers barely move, as the S-CVAE does where the keyframes imply little travel;
a k-NN distance of the window (the motion bank's match features) to the training takes did not predict where it
loses (Spearman 0.02, docs/results/gate.md).  ``ood.npz`` in the run (or shipped) folder holds scorer and gate;
``model.ood_gate`` switches the blend on.  Only a known gap is gated (``inbetween infill`` always knows it; the
bench's guessed-gap rows are not gated).

``model.departure_cap = c`` also bounds how far the fill may leave interpolation: by at most ``c`` times
interpolation's own error as predicted from the context alone (:func:`predicted_base_error_cm`, a log-linear fit
on the ``fit`` takes' windows stored in ``ood.npz``).  The blend's error is at most interpolation's plus the
departure it keeps (triangle inequality), so a fill that runs far from a window that interpolation gets nearly
right is pulled back even when the dancers move fast, which the speed score alone lets through.
"""
from __future__ import annotations

import numpy as np

__all__ = ["window_context", "interpolation_base", "gate_blend", "gate_rollouts", "base_error_features",
           "fit_base_error", "predicted_base_error_cm", "departure_cm", "departure_weight", "BASE_ERROR_KEY"]

BASE_ERROR_KEY = "base_error_coef"        # ood.npz: the coefficients of :func:`predicted_base_error_cm`


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


def base_error_features(context, keypose, frames: int) -> np.ndarray:
    """(B, 4) features of B windows for :func:`predicted_base_error_cm`: 1, log gap (frames), log joint speed at
    the last context frame (cm per frame, + 0.1) and log mean keypose distance from it (cm, + 0.1);
    context (B, 2, >= 2, J, >= 3), keypose (B, 2, J, >= 3), positions in metres."""
    speed = window_context(context)[:, 0]
    c, k = np.asarray(context, np.float64)[:, :, -1, :, :3], np.asarray(keypose, np.float64)[..., :3]
    reach = 100.0 * np.linalg.norm(k - c, axis=-1).mean((1, 2))
    return np.c_[np.ones(len(speed)), np.full(len(speed), np.log(frames)), np.log(speed + 0.1), np.log(reach + 0.1)]


def fit_base_error(features, errors_cm) -> np.ndarray:
    """Least-squares coefficients (4,) of log interpolation error (cm) on :func:`base_error_features` (N, 4)."""
    return np.linalg.lstsq(np.asarray(features, np.float64), np.log(np.maximum(errors_cm, 1e-6)), rcond=None)[0]


def predicted_base_error_cm(coef, context, keypose, frames: int) -> np.ndarray:
    """(B,) interpolation's joint error (cm) over the gap as predicted from the context and keyposes alone."""
    return np.exp(base_error_features(context, keypose, frames) @ np.asarray(coef, np.float64))


def departure_cm(rollout, base) -> np.ndarray:
    """(B,) mean joint distance (cm) of a rollout (B, 2, >= n, J, >= 3) from the base (B, 2, n, J, >= 3) over
    the base's n frames."""
    n = base.shape[2]
    d = np.asarray(rollout, np.float64)[:, :, :n, :, :3] - np.asarray(base, np.float64)[..., :3]
    return 100.0 * np.linalg.norm(d, axis=-1).mean((1, 2, 3))


def departure_weight(cap: float, predicted_cm, away_cm) -> np.ndarray:
    """(B,) the largest weights <= 1 at which a fill ``away_cm`` from interpolation departs at most ``cap`` times
    the predicted interpolation error (1 everywhere when ``cap`` <= 0)."""
    away = np.asarray(away_cm, np.float64)
    if cap <= 0:
        return np.ones_like(away)
    return np.minimum(1.0, cap * np.asarray(predicted_cm, np.float64) / np.maximum(away, 1e-9))


def gate_rollouts(gate, rollouts, context, keypose, gaps, cap: float = 0.0, coef=None, parts: dict | None = None,
                  samples: bool = True):
    """The gate ((scorer, Gate)) on rollouts (S, B, 2, F, J, 9) of B windows with contexts (B, 2, n_input, J, 9),
    keyposes (B, 2, J, 9) and gaps (B,) (all one length).  With ``cap`` > 0 and the base-error coefficients
    ``coef``, the weight is also held to :func:`departure_weight` of sample 0 (every sample gets its window's
    weight; with ``samples`` false (``model.bank_sample_gated``) only sample 0 is gated and samples s >= 1 are
    returned as they came).  Returns (rollouts, score (B,), weight (B,)); ``parts`` (a dict, when given) receives
    ``speed_weight`` and ``departure_weight`` (B,)."""
    gaps = np.asarray(gaps).astype(int)
    if len(np.unique(gaps)) != 1:
        raise ValueError("gate_rollouts: windows of one gap length at a time")
    score = gate[0].score(window_context(context))
    weight = gate[1].weight(score)
    base = interpolation_base(context, keypose, int(gaps[0]))
    capped = np.ones_like(weight)
    if cap > 0:
        if coef is None:
            raise ValueError("gate_rollouts: model.departure_cap needs the base-error coefficients of ood.npz")
        capped = departure_weight(cap, predicted_base_error_cm(coef, context, keypose, int(gaps[0])),
                                  departure_cm(np.asarray(rollouts)[0], base))
    if parts is not None:
        parts.update(speed_weight=weight, departure_weight=capped)
    if samples:
        return gate_blend(rollouts, base, weight * capped), score, weight * capped
    out = np.array(rollouts, np.float32)                       # only sample 0, the deterministic fill, is gated
    out[:1] = gate_blend(out[:1], base, weight * capped)
    return out, score, weight * capped
