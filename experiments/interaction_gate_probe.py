"""Which score predicts where the interaction model loses to interpolation?  On the validation take only.

    python experiments/interaction_gate_probe.py RUN_DIR [--source ../shared/data/cmu_pairs]

RUN_DIR must hold a calibrated gate (``inbetween calibrate-gate RUN_DIR``): its ``ood_calibration.json`` gives each
validation window's error ratio to interpolation at each blend weight.  For each candidate score, per window: the
Spearman correlation with the ratio of the learned fill alone, and the gate ``calibrate_gate`` chooses with it
(mean / p90 / max of the gated ratios).  Candidates: the k-NN distance of the window's match features (the motion
bank's, plus the gap) to the ``fit`` takes' windows, also with the two dancers' placement at the keyframe
(:func:`~inbetween_jax.models.interaction.bank.pair_features` at weight :data:`PAIR_WEIGHT`); the joint speed at the last context frame (what ships); the
keypose's distance per frame; the spread of the ensemble's members relative to the network's departure from
interpolation.
"""
import argparse
import dataclasses
import json
import os

import numpy as np

PAIR_WEIGHT = 3.0         # the shipped model.bank_pair_weight


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    a = p.parse_args()
    import jax
    from scipy.stats import spearmanr
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bank import MotionBank, match_features, pair_features
    from inbetween_jax.models.interaction.bench import _model_method, member
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.gate import interpolation_base, window_context
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.ood import build_bank, calibrate_gate
    from inbetween_jax.train.run import load_run
    tr = dataclasses.replace(load(load_run(a.run_dir)), gate=None)      # the network as trained, ungated
    d, n = tr.cfg.data, proto.N_INPUT
    cal = json.load(open(os.path.join(a.run_dir, "ood_calibration.json")))["records"]
    pairs = load_pairs(a.source, d.pair_distance)
    fit, val = (split_pairs(pairs, s, tuple(d.split)) for s in ("fit", "val"))
    mb = MotionBank.from_pairs(fit, d.pos_scale)
    gaps = sorted({r["frames"] for r in cal})
    knn = build_bank(np.concatenate([np.c_[mb.index(n, g), np.full(len(mb.index(n, g)), g / 30)] for g in gaps]))
    knn_pair = build_bank(np.concatenate([np.c_[mb.index(n, g), PAIR_WEIGHT * mb.pair_index(n, g),
                                                np.full(len(mb.index(n, g)), g / 30)] for g in gaps]))
    windows = proto.table1_windows(val, d.pos_scale, 64, tuple(gaps))
    cand = {k: [] for k in ("k-NN distance to the fit takes", "the same with the pair's placement",
                            "joint speed (shipped)", "keypose distance per frame",
                            "member spread / departure")}
    for L in gaps:
        b, ctx = windows[L], windows[L]["x"][:, :, :n]
        cand["k-NN distance to the fit takes"] += list(knn.score(np.c_[match_features(ctx, b["keypose"]),
                                                                       np.full(len(ctx), L / 30)]))
        cand["the same with the pair's placement"] += list(knn_pair.score(np.c_[
            match_features(ctx, b["keypose"]), PAIR_WEIGHT * pair_features(b["rel_R"], b["rel_t"]),
            np.full(len(ctx), L / 30)]))
        cand["joint speed (shipped)"] += list(-window_context(ctx)[:, 0])
        kd = np.linalg.norm(b["keypose"][..., :3] - ctx[:, :, -1, :, :3], axis=-1).mean((1, 2)) / L
        cand["keypose distance per frame"] += list(-kd)
        runs = np.stack([np.asarray(_model_method(member(tr, i), use_bank=False)(b, -(-L // d.n_pred), 1,
                                                                                 jax.random.key(L)))[0, :, :, :L]
                         for i in range(tr.cfg.model.members)])[..., :3]
        spread = np.mean([np.linalg.norm(runs[i] - runs[j], axis=-1).mean((1, 2, 3))
                          for i in range(len(runs)) for j in range(i + 1, len(runs))], 0)
        base = interpolation_base(ctx, b["keypose"], L)[..., :3]
        away = np.linalg.norm(runs.mean(0) - base, axis=-1).mean((1, 2, 3))
        cand["member spread / departure"] += list(spread / (away + 1e-6))
    ratio = np.array([r["ratios_at"][-1] for r in cal])
    at, groups = [r["ratios_at"] for r in cal], [str(r["frames"]) for r in cal]
    print(f"{len(cal)} validation windows; the learned fill alone: mean {ratio.mean():.3f}, p90 "
          f"{np.quantile(ratio, 0.9):.3f}, max {ratio.max():.3f} (higher score = slower / farther / more spread)")
    print("| score | Spearman with the ratio | gated mean | p90 | max |\n|---|---|---|---|---|")
    for name, v in cand.items():
        _, s = calibrate_gate(v, at, groups=groups)
        print(f"| {name} | {spearmanr(v, ratio)[0]:.2f} | {s['mean']:.3f} | {s['p90']:.3f} | {s['max']:.3f} |")


if __name__ == "__main__":
    main()
