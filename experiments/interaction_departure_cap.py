"""Choose the interaction model's departure cap (``model.departure_cap``) on the validation take.

    python experiments/interaction_departure_cap.py RUN_DIR [--caps 2,1.5,1.25,1,0.9,0.8,0.75,0.7,0.6,0.5]
                                                   [--source ../shared/data/cmu_pairs] [--test]

Calibrates the run's gate once (:func:`inbetween_jax.models.interaction.calibrate.calibrate`: each validation
window's error ratio to interpolation at the blend weights, and the fill's departure from interpolation over the
interpolation error predicted from the context), then, per cap, the speed gate's thresholds chosen with the cap in
place (:func:`inbetween_jax.models.ood.calibrate_gate`) and the per-window mean / p90 / max of the gated ratios,
per length and pooled.  The rule: the lowest pooled mean; among caps within 0.001 of it, the lowest maximum.
``--test`` scores the test takes' windows at the chosen thresholds instead (look once, after the choice): the
network, bank, gate and easing as ``inbetween infill`` runs them, exactly (no interpolation between weights).
"""
import argparse
import dataclasses

import numpy as np


def summary(r) -> str:
    return f"{r.mean():.3f} / {np.quantile(r, 0.9):.3f} / {r.max():.3f}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--caps", default="2,1.5,1.25,1,0.9,0.8,0.75,0.7,0.6,0.5")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    p.add_argument("--test", action="store_true", help="score the test takes at each cap (after the choice)")
    a = p.parse_args()
    from inbetween_jax.models.interaction.calibrate import calibrate
    from inbetween_jax.models.interaction.gate import departure_weight
    from inbetween_jax.models.ood import calibrate_gate, gated_ratio
    from inbetween_jax.train.run import load_run
    run = load_run(a.run_dir)
    caps = [0.0] + [float(c) for c in a.caps.split(",")]
    res = calibrate(run, a.source)
    recs = res["records"]
    frames = np.array([r["frames"] for r in recs])
    scores, at = [r["score"] for r in recs], [r["ratios_at"] for r in recs]
    dep = np.array([r["departure"] for r in recs])
    print(f"{len(recs)} validation windows; departure / predicted interpolation error: median {np.median(dep):.2f}, "
          f"max {dep.max():.2f}")
    lengths = sorted(set(frames.tolist()))
    print("| cap | gate lo / hi | " + " | ".join(f"{L}: mean / p90 / max" for L in lengths) +
          " | pooled mean / p90 / max |\n|---|---|" + "---|" * (len(lengths) + 1))
    chosen = {}
    for c in caps:
        cap_w = departure_weight(c, 1.0, dep)           # departure is already over the predicted error
        gate, _ = calibrate_gate(scores, at, groups=[str(f) for f in frames], scale=cap_w)
        r = gated_ratio(at, gate.weight(scores) * cap_w)
        chosen[c] = (r.mean(), r.max(), gate)
        print(f"| {c or 'off'} | {gate.lo:.4f} / {gate.hi:.4f} | " +
              " | ".join(summary(r[frames == L]) for L in lengths) + f" | {summary(r)} |")
    low = min(m for m, _, _ in chosen.values())
    pick = min((c for c in caps if chosen[c][0] <= low + 1e-3), key=lambda c: chosen[c][1])
    print(f"chosen: cap {pick} (gate lo {chosen[pick][2].lo:.4f}, hi {chosen[pick][2].hi:.4f})")
    if a.test:
        test(run, a.source, [0.0, pick], {c: chosen[c][2] for c in (0.0, pick)}, lengths,
             res["arrays"]["base_error_coef"])


def test(run, source, caps, gates, lengths, coef) -> None:
    """Every test window, one sample, true gap: the ratio to interpolation at each cap with its thresholds."""
    import jax
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bank import ease_into_keypose
    from inbetween_jax.models.interaction.bench import _model_method
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.gate import gate_rollouts, interpolation_base
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.interaction.samples import window_errors_cm
    trained = load(run)
    d, m = trained.cfg.data, trained.cfg.model
    plain = dataclasses.replace(trained, cfg=dataclasses.replace(trained.cfg, model=dataclasses.replace(
        m, ease_frames=0, ood_gate=False)))
    pairs = split_pairs(load_pairs(source, d.pair_distance), "test", tuple(d.split))
    rows = {c: [] for c in caps}
    for L, b in proto.table1_windows(pairs, d.pos_scale, 10_000, lengths).items():
        ctx = b["x"][:, :, :proto.N_INPUT]
        learned = np.asarray(_model_method(plain)(b, -(-L // d.n_pred), 1, jax.random.key(L)))[:, :, :, :L]
        base = np.maximum(window_errors_cm(interpolation_base(ctx, b["keypose"], L), b), 1e-6)
        for c in caps:
            out = gate_rollouts((trained.gate[0], gates[c]), learned, ctx, b["keypose"], np.full(len(ctx), L),
                                cap=c, coef=coef)[0]
            out = ease_into_keypose(out, b["keypose"], np.full(len(ctx), L), m.ease_frames)
            rows[c].append(window_errors_cm(out[0], b) / base)
    print("test takes | " + " | ".join(f"{L}: mean / p90 / max" for L in lengths) + " | pooled |")
    for c in caps:
        print(f"cap {c or 'off'} | " + " | ".join(summary(r) for r in rows[c]) + f" | {summary(np.concatenate(rows[c]))} |")


if __name__ == "__main__":
    main()
