"""Calibration of the S-CVAE's out-of-distribution gate (:mod:`.gate`, :mod:`inbetween_jax.models.ood`) on the
validation split of the run's training data: ``inbetween calibrate-gate RUN_DIR``."""
from __future__ import annotations

import numpy as np


def calibrate(run, source: str, samples: int = 4, lengths=(10, 30, 50), n_past: int = 10, kind: str = "travel",
              travel_c: float = 1.0, in_clip: bool = True) -> dict:
    """Choose the gate on the validation split of the run's training data (never the test windows).

    kind: the gate's score -- ``"travel"`` (:class:`~inbetween_jax.models.ood.TravelScore`, ``travel_c`` data
    units per frame; the default, chosen on the validation subjects) or ``"knn"`` (the k-NN distance of the
    keyframe context to the training split's, :class:`~inbetween_jax.models.ood.ContextBank`).  Both are
    recorded per window (``score``: the gate's, ``knn_score``).  Returns ``{"bank" (the scorer), "gate",
    "summary", "records"}``; records: one dict per validation window and length (``name``, ``frames``,
    ``score``, ``knn_score``, ``ratios_at`` (error / Slerp's at each of
    :data:`~inbetween_jax.models.ood.BLEND_WEIGHTS`), ``base_cm``).

    in_clip: also choose the thresholds used inside a clip (:func:`~.gate.context_gate`) by the same rule, on
    :func:`in_clip_records` of the same validation motions (``arrays``: :data:`~.gate.CONTEXT_GATE_KEYS`;
    ``context_records``; the summary's ``context_*`` numbers)."""
    from inbetween_jax.data import load_dataset
    from inbetween_jax.data.datasets import val_split_of
    from inbetween_jax.models.ood import BLEND_WEIGHTS, TravelScore, calibrate_gate
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.bench import per_frame_error
    from inbetween_jax.models.scvae.gate import gate_blend, keyframe_context, slerp_base, training_bank
    trained = infer.load(run)
    split = run.config.get("train", {}).get("split", "fit")
    fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
    bank = training_bank(source, split, fa)
    travel = TravelScore(int(trained.extra["num_joints"]), float(travel_c))
    val = load_dataset(source, val_split_of(split), window=n_past + max(lengths) + 5, offset=20)
    records, k0 = [], n_past - 1
    for n in lengths:
        k1 = n_past + n
        a = (val.local_quats[:, k0], val.root_pos[:, k0], val.local_quats[:, k1], val.root_pos[:, k1])
        s = infer.sample_transitions(trained.cfg.model, trained.state, val, n_past, n, samples, bank=trained.bank,
                                     sampled=False)          # the fill the gate blends, not the sampled mode
        bq, br = slerp_base(*a, n)
        base = per_frame_error(val, n_past, n, bq[None], br[None])[0].mean(-1)               # (B,)
        at = np.stack([per_frame_error(val, n_past, n, *gate_blend(s["q"], s["r"], bq, br, np.full(len(val), w)))
                       .mean((0, 2)) for w in BLEND_WEIGHTS], 1) / np.maximum(base, 1e-6)[:, None]
        ctx = keyframe_context(*a, n, val.skeleton, fa)
        knn, score = bank.score(ctx), (travel if kind == "travel" else bank).score(ctx)
        records += [{"name": val.seq_names[i], "frames": n, "score": float(score[i]), "knn_score": float(knn[i]),
                     "ratios_at": at[i].tolist(), "base_cm": float(base[i])} for i in range(len(val))]
    from inbetween_jax.data.activities import activity_group
    gate, summary = calibrate_gate([r["score"] for r in records], [r["ratios_at"] for r in records],
                                   groups=[f"{activity_group(r['name'])}/{r['frames']}" for r in records])
    out = {"bank": travel if kind == "travel" else bank, "gate": gate,
           "summary": dict(summary, lo=gate.lo, hi=gate.hi, kind=kind), "records": records}
    if in_clip:
        inside = calibrate_in_clip(run, source, lengths, trained=trained, scorer=out["bank"], knn=bank)
        out["summary"].update(inside.pop("summary"))
        out.update(inside)
    return out


def calibrate_in_clip(run, source: str, lengths=(10, 30, 50), trained=None, scorer=None, knn=None) -> dict:
    """The gate's thresholds inside a clip (:func:`~.gate.context_gate`), chosen by
    :func:`~inbetween_jax.models.ood.calibrate_gate`'s rule on :func:`in_clip_records` of the run's validation
    split, with ``scorer`` (default: the travel score).  Returns ``{"arrays": {CONTEXT_GATE_KEYS: (lo, hi)},
    "summary": {"context_*": ...}, "context_records"}``."""
    from inbetween_jax.data import load_motions
    from inbetween_jax.data.activities import activity_group
    from inbetween_jax.data.datasets import val_split_of
    from inbetween_jax.models.ood import calibrate_gate
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.gate import CONTEXT_GATE_KEYS
    trained = trained or infer.load(run)
    fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
    split = run.config.get("train", {}).get("split", "fit")
    inside = in_clip_records(trained, load_motions(source, val_split_of(split)), fa, lengths, scorer=scorer, knn=knn)
    gate, summary = calibrate_gate([r["score"] for r in inside], [r["ratios_at"] for r in inside],
                                   groups=[f"{activity_group(r['name'])}/{r['frames']}" for r in inside])
    return {"arrays": dict(zip(CONTEXT_GATE_KEYS, (gate.lo, gate.hi))), "context_records": inside,
            "summary": dict({f"context_{k}": v for k, v in summary.items()}, context_lo=gate.lo, context_hi=gate.hi)}


def in_clip_records(trained, motions, forward_axis, lengths=(10, 30, 50), stride: int = 45, first: int = 3,
                    scorer=None, knn=None) -> list:
    """Gaps inside clips, filled as ``inbetween infill`` fills them (the frames beside the keyframes passed, the
    fill onto the Hermite path through them: ``model.context_base`` switched on here): every ``stride`` frames
    from frame ``first`` of each motion, ``lengths`` frames.  A record per gap: ``name`` (``file:frame``, the file
    name only), ``frames``, ``score`` (``scorer``'s, default the travel score) and ``knn_score`` (``knn``'s, a
    :class:`~inbetween_jax.models.ood.ContextBank`, when given) of its keyframe context, ``ratios_at`` (joint
    error over the Hermite path's at each learned-fill weight of :data:`~inbetween_jax.models.ood.BLEND_WEIGHTS`)
    and ``base_x_slerp`` (the path's error over Slerp's)."""
    import dataclasses
    import os
    from inbetween_jax.models.ood import BLEND_WEIGHTS, Gate, TravelScore
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.context import clip_keyframes
    from inbetween_jax.models.scvae.gate import keyframe_context, slerp_base
    cfg = trained.cfg
    cfg = dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, context_base=True, ood_gate=True,
                                                             context_gate=False))
    scorer = scorer or TravelScore(trained.skeleton.num_joints)
    at = {w: dataclasses.replace(trained, cfg=cfg, gate=(_Zero(), Gate(w - 1.0, w))) for w in BLEND_WEIGHTS}
    records = []
    for m in motions:
        gp = m.global_positions()
        for n in lengths:
            for k0 in range(first, m.num_frames - n - 2, stride):
                k1 = k0 + n + 1
                s, e = clip_keyframes(m, k0, k1)
                def err_of(q, r):                # mean joint error of a fill (n, J, 4), (n, 3) of the gap
                    return float(np.linalg.norm(m.positions_of(q, r) - gp[k0 + 1:k1], axis=-1).mean())
                err = {}
                for w, t in at.items():
                    out = infer.infill_between(t, m.skeleton, s, e, n, 1, 0, forward_axis)
                    err[w] = err_of(out["q"][0, 1:-1], out["r"][0, 1:-1])
                keys = [x[k][None] for x, k in ((m.local_quats, k0), (m.root_pos, k0), (m.local_quats, k1),
                                                (m.root_pos, k1))]
                sq, sr = slerp_base(*keys, n)
                slerp = err_of(sq[0], sr[0])
                ctx = keyframe_context(*keys, n, m.skeleton, forward_axis)
                base = max(err[0.0], 1e-9)
                records.append({"name": f"{os.path.basename(str(m.source))}:{k0}", "frames": n,
                                "score": float(scorer.score(ctx)[0]),
                                **({"knn_score": float(knn.score(ctx)[0])} if knn is not None else {}),
                                "ratios_at": [err[w] / base for w in BLEND_WEIGHTS],
                                "base_x_slerp": base / max(slerp, 1e-9)})
    return records


class _Zero:
    """A scorer giving every context 0: with ``Gate(w - 1, w)`` the learned fill is kept at weight w."""

    def score(self, desc):
        return np.zeros(len(desc))


def calibrate_additions(run, source: str) -> dict:
    """What :func:`calibrate` adds to the gate, alone (``inbetween calibrate-gate RUN_DIR --keep-gate``): the
    thresholds inside a clip (:func:`calibrate_in_clip`)."""
    return calibrate_in_clip(run, source)
