"""Calibration of the S-CVAE's out-of-distribution gate (:mod:`.gate`, :mod:`inbetween_jax.models.ood`) on the
validation split of the run's training data: ``inbetween calibrate-gate RUN_DIR``."""
from __future__ import annotations

import numpy as np


def calibrate(run, source: str, samples: int = 4, lengths=(10, 30, 50), n_past: int = 10, kind: str = "travel",
              travel_c: float = 1.0) -> dict:
    """Choose the gate on the validation split of the run's training data (never the test windows).

    kind: the gate's score -- ``"travel"`` (:class:`~inbetween_jax.models.ood.TravelScore`, ``travel_c`` data
    units per frame; the default, chosen on the validation subjects) or ``"knn"`` (the k-NN distance of the
    keyframe context to the training split's, :class:`~inbetween_jax.models.ood.ContextBank`).  Both are
    recorded per window (``score``: the gate's, ``knn_score``).  Returns ``{"bank" (the scorer), "gate",
    "summary", "records"}``; records: one dict per validation window and length (``name``, ``frames``,
    ``score``, ``knn_score``, ``ratios_at`` (error / Slerp's at each of
    :data:`~inbetween_jax.models.ood.BLEND_WEIGHTS`), ``base_cm``)."""
    from inbetween_jax.data import load_dataset
    from inbetween_jax.data.datasets import val_split_of
    from inbetween_jax.models.ood import BLEND_WEIGHTS, TravelScore, build_bank, calibrate_gate
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.bench import per_frame_error
    from inbetween_jax.models.scvae.gate import gate_blend, keyframe_context, slerp_base, training_contexts
    trained = infer.load(run)
    split = run.config.get("train", {}).get("split", "fit")
    fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
    train = load_dataset(source, split, window=60, offset=20)
    bank = build_bank(training_contexts(train, fa))
    travel = TravelScore(int(train.skeleton.num_joints), float(travel_c))
    val = load_dataset(source, val_split_of(split), window=n_past + max(lengths) + 5, offset=20)
    records, k0 = [], n_past - 1
    for n in lengths:
        k1 = n_past + n
        a = (val.local_quats[:, k0], val.root_pos[:, k0], val.local_quats[:, k1], val.root_pos[:, k1])
        s = infer.sample_transitions(trained.cfg.model, trained.state, val, n_past, n, samples, bank=trained.bank)
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
    return {"bank": travel if kind == "travel" else bank, "gate": gate,
            "summary": dict(summary, lo=gate.lo, hi=gate.hi, kind=kind), "records": records}
