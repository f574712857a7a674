"""Calibration of the CAE's out-of-distribution gate (:mod:`.gate`, :mod:`inbetween_jax.models.ood`) on the
validation split of the run's training data, and the bench's per-window (worst-case) rows."""
from __future__ import annotations

import numpy as np


def per_window_rows(positions, names, methods, data, runs, models) -> list:
    """Worst-case rows (:mod:`inbetween_jax.evaluation.worst_case`) of every learned method: each clip's error
    over every gap position as a ratio to the limited Hermite fill's (the bench's ``hermite`` row) and to linear
    fill's, on the test clips; plus the validation subjects from a gated run's ``ood_calibration.json`` (its
    calibration gaps at the gate's weights, ratio to the fill the gate falls back to, "its base")."""
    from inbetween_jax.evaluation.worst_case import worst_case_rows
    from inbetween_jax.models.ood_runs import calibration_worst_case
    out = []
    for m in methods:
        if m in ("linear", "hermite"):
            continue
        for base, label in (("hermite", "the limited Hermite fill"), ("linear", "linear fill")):
            recs = [{"name": n, "frames": positions[m][s]["frames"], "ratio": float(o / max(b, 1e-6))}
                    for s in positions[m] for n, o, b in zip(names, positions[m][s]["per_clip"],
                                                             positions[base][s]["per_clip"])]
            out += worst_case_rows(recs, "per_window", data, "cae", label, "test")
        out += calibration_worst_case(runs[m].run_dir, getattr(models[m], "gate", None), "cae", "its base")
    return out


def calibrate(run, source: str, seconds=(1, 2), clip: int = 96, positions=(-12, 0, 12), kind: str = "travel",
              floor_c: float = 1.0, split: str | None = None) -> dict:
    """Build the bank from the run's training split and choose the gate on its validation split (never the
    test clips): gaps of ``seconds`` centred in each validation clip and shifted by ``positions`` frames.

    kind: the gate's score -- ``"travel"`` (the root's floor speed beside the gap, :func:`.gate.floor_scorer`,
    ``floor_c`` data units per frame; the default since 2026-12-06, chosen on the validation subjects) or
    ``"knn"`` (the k-NN distance of the gap's context to the training split's,
    :class:`~inbetween_jax.models.ood.ContextBank`).  Both are recorded per gap.
    split: the motions scored (default: the validation split of the run's training split; another, e.g.
    ``val-activities``, only to study the records: the gate is chosen on those motions).
    With ``kind="travel"`` also the k-NN cap (:func:`.gate.knn_cap`; ``arrays``, the summary's ``knn_cap_*``).
    Returns ``{"bank" (the scorer), "gate", "summary", "records"}``; a record per clip and gap (``name`` the clip,
    ``frames``, ``score`` (the gate's), ``knn_score``, ``floor_speed``, ``ratios_at``: body-frame joint error /
    the pre-fill's at each blend weight)."""
    from inbetween_jax.data import load_motions
    from inbetween_jax.evaluation import infilling as proto
    from inbetween_jax.models.cae.features import body_positions
    from inbetween_jax.data.datasets import val_split_of
    from inbetween_jax.models.cae.gate import (KNN_CAP_PREFIX, base_fill, floor_scorer, gap_context,
                                               knn_cap_thresholds, training_contexts)
    from inbetween_jax.models.cae.infer import fill, load
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    from inbetween_jax.models.cae.train import load_data
    from inbetween_jax.models.ood import BLEND_WEIGHTS, build_bank, calibrate_gate
    model = load(run)
    scored, split = split, run.config.get("train", {}).get("split", "fit")
    if kind not in ("knn", "travel"):
        raise ValueError(f"unknown gate score {kind!r}: knn or travel")
    bank = build_bank(training_contexts(load_data(model.cfg, source, split).bank))
    floor = floor_scorer(model.normalizer, model.num_joints, floor_c)
    motions = load_motions(source, val_split_of(split) if scored is None else scored)
    x = proto.test_clips(motions, model.normalizer, clip, clip // 2)
    names = [short_name(m.source) for m in motions for s in range(0, m.num_frames - clip + 1, clip // 2)]
    truth = body_positions(x, model.normalizer, model.num_joints)
    records = []
    for sec in seconds:
        g = int(round(sec * float(motions[0].fps)))
        for shift in positions:
            a = (clip - g) // 2 + shift
            if a < 8 or a + g > clip - 8:
                continue
            fm = np.broadcast_to(gap_frames(clip, [(a, a + g)]), (len(x), clip))
            mask = frame_mask_image(fm, model.num_joints)
            learned, base = fill(model, x, mask, gate=False), base_fill(model, x, mask)

            def err(y):
                d = np.linalg.norm(body_positions(y, model.normalizer, model.num_joints) - truth, axis=-1)
                return d[:, a:a + g].mean((1, 2))
            b_err = np.maximum(err(base), 1e-6)
            at = np.stack([err(base + w * (learned - base)) for w in BLEND_WEIGHTS], 1) / b_err[:, None]
            ctx = gap_context(x, a, a + g)
            knn, speed = bank.score(ctx), floor.speed(ctx)
            score = knn if kind == "knn" else floor.score(ctx)
            records += [{"name": names[i], "frames": g, "score": float(score[i]), "knn_score": float(knn[i]),
                         "floor_speed": float(speed[i]), "ratios_at": at[i].tolist(), "base_cm": float(b_err[i])}
                        for i in range(len(x))]
    from inbetween_jax.data.activities import activity_group
    gate, summary = calibrate_gate([r["score"] for r in records], [r["ratios_at"] for r in records],
                                   groups=[f"{activity_group(r['name'])}/{r['frames']}" for r in records])
    out = {"bank": bank if kind == "knn" else floor, "gate": gate,
           "summary": dict(summary, lo=gate.lo, hi=gate.hi, kind=kind), "records": records}
    if kind == "travel":                     # the k-NN cap (gate.knn_cap) from the same validation gaps
        cap = knn_cap_thresholds([r["knn_score"] for r in records])
        out["arrays"] = dict(bank.arrays(KNN_CAP_PREFIX + "bank_"), **{f"{KNN_CAP_PREFIX}gate_lo": cap.lo,
                                                                       f"{KNN_CAP_PREFIX}gate_hi": cap.hi})
        out["summary"].update(knn_cap_lo=cap.lo, knn_cap_hi=cap.hi)
    return out


def calibrate_additions(run, source: str) -> dict:
    """What :func:`calibrate` adds to the gate, alone (``inbetween calibrate-gate RUN_DIR --keep-gate``): the
    k-NN cap from the run's validation gaps.  Returns ``{"arrays", "summary"}``."""
    res = calibrate(run, source, kind="travel")
    return {"arrays": res["arrays"], "summary": {k: v for k, v in res["summary"].items() if k.startswith("knn_cap")}}


def short_name(path: str) -> str:
    """``<folder>/<file>`` of a clip's path: enough to name its CMU trial and activity, and no machine's folders
    in the calibration file that ships with the weights."""
    import os
    return "/".join(os.path.normpath(str(path)).split(os.sep)[-2:])
