"""Calibration of the interaction model's out-of-distribution gate (:mod:`.gate`, :mod:`inbetween_jax.models.ood`)
on the validation take of the run's training pairs (never the test takes)."""
from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["calibrate"]


def calibrate(run, source: str, lengths=(30, 50), max_windows: int = 64) -> dict:
    """Choose the gate (a :class:`~inbetween_jax.models.ood.SpeedScore`, :mod:`.gate`) on the validation take:
    every window of ``lengths`` frames (true gap), one sample, at each blend weight toward interpolation (then
    eased onto the keypose as the run's config says).  Also fits interpolation's error from the context
    (:func:`.gate.fit_base_error`) on the ``fit`` takes' windows, for ``model.departure_cap``; with the cap on, the
    thresholds are chosen with it in place.  Returns ``{"bank", "gate", "summary", "records", "arrays"}``; a record
    per window (``name`` take@frame, ``frames``, ``score``, ``ratios_at``: joint error / interpolation's,
    ``base_cm``, ``departure``: the fill's distance from interpolation over the predicted interpolation error,
    ``cap_weight``: :func:`.gate.departure_weight` at the run's cap)."""
    import jax
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bank import ease_into_keypose
    from inbetween_jax.models.interaction.bench import _model_method
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.gate import (BASE_ERROR_KEY, base_error_features, departure_cm,
                                                       departure_weight, fit_base_error, gate_blend,
                                                       interpolation_base, predicted_base_error_cm, window_context)
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.interaction.samples import window_errors_cm
    from inbetween_jax.models.ood import BLEND_WEIGHTS, SpeedScore, calibrate_gate
    trained = load(run, with_gate=False)                  # the gate is what is being calibrated
    d, ease = trained.cfg.data, trained.cfg.model.ease_frames
    plain = dataclasses.replace(trained, cfg=dataclasses.replace(
        trained.cfg, model=dataclasses.replace(trained.cfg.model, ease_frames=0, ood_gate=False)))
    pairs = load_pairs(source or run.data.get("source"), d.pair_distance)
    val, fit = (split_pairs(pairs, s, tuple(d.split)) for s in ("val", "fit"))
    if not val or not fit:
        raise ValueError(f"{source}: no validation take to calibrate the gate on, or no training take beside it")
    feats, errs = [], []
    for L, b in proto.table1_windows(fit, d.pos_scale, 400, lengths).items():     # interpolation alone
        ctx = b["x"][:, :, :proto.N_INPUT]
        feats.append(base_error_features(ctx, b["keypose"], L))
        errs.append(window_errors_cm(interpolation_base(ctx, b["keypose"], L), b))
    coef, cap = fit_base_error(np.concatenate(feats), np.concatenate(errs)), trained.cfg.model.departure_cap
    bank = SpeedScore()
    windows = proto.table1_windows(val, d.pos_scale, max_windows, lengths)
    method, records = _model_method(plain), []
    for L in lengths:
        b = windows.get(L)
        if not b:
            continue
        ctx = b["x"][:, :, :proto.N_INPUT]
        learned = np.asarray(method(b, -(-L // d.n_pred), 1, jax.random.key(L)))[:, :, :, :L]
        base = interpolation_base(ctx, b["keypose"], L)
        gaps = np.full(len(ctx), L)
        errs = []
        for w in BLEND_WEIGHTS:
            y = gate_blend(learned, base, np.full(len(ctx), w))
            y = ease_into_keypose(y, b["keypose"], gaps, ease) if ease else y
            errs.append(window_errors_cm(y[0], b))
        base_cm = np.maximum(window_errors_cm(base, b), 1e-6)
        at = np.stack(errs, 1) / base_cm[:, None]
        score = bank.score(window_context(ctx))
        predicted, away = predicted_base_error_cm(coef, ctx, b["keypose"], L), departure_cm(learned[0], base)
        capped = departure_weight(cap, predicted, away)
        records += [{"name": b["names"][i], "frames": L, "score": float(score[i]), "ratios_at": at[i].tolist(),
                     "base_cm": float(base_cm[i]), "departure": float(away[i] / predicted[i]),
                     "cap_weight": float(capped[i])} for i in range(len(ctx))]
    gate, summary = calibrate_gate([r["score"] for r in records], [r["ratios_at"] for r in records],
                                   groups=[str(r["frames"]) for r in records],
                                   scale=[r["cap_weight"] for r in records])
    return {"bank": bank, "gate": gate, "records": records, "arrays": {BASE_ERROR_KEY: coef},
            "summary": dict(summary, lo=gate.lo, hi=gate.hi, kind="speed", departure_cap=float(cap))}
