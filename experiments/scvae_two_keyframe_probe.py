"""Between two keyframes, on activities the network never saw: can another score, or thresholds chosen with those
activities in view, keep the S-CVAE's gate at or below Slerp there without giving up the validation walks?

    python experiments/scvae_two_keyframe_probe.py [RUN_DIR]     # default runs/scvae_wo_activities, ~3 min

RUN_DIR: an S-CVAE trained on ``fit-activities`` with a calibrated gate (``inbetween calibrate-gate``).  Its
windows of ``val-subjects`` (held-out people) and ``val-activities`` (held-out people and activities), Table-1
layout (65-frame windows every 20 frames, 10 / 30 / 50 frames), each scored at the blend weights of
:data:`~inbetween_jax.models.ood.BLEND_WEIGHTS` (4 samples, the fill, not the sampled mode).  Prints the run's
travel gate, the network alone, a cap on the forward and backward generators' disagreement at the middle frame
(in cm, and over Slerp's error; thresholds by the gate's rule on ``val-subjects`` with the travel weight as
scale, and by the CAE cap's quantiles 0.9 / max), and the travel gate re-chosen on both splits together.
"""
import argparse
import collections
import time

import numpy as np

from inbetween_jax.data import load_dataset
from inbetween_jax.data.activities import activity_group
from inbetween_jax.models.ood import BLEND_WEIGHTS, Gate, calibrate_gate, gated_ratio, load_gate
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.bench import per_frame_error
from inbetween_jax.models.scvae.gate import gate_blend, keyframe_context, slerp_base
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir", nargs="?", default="runs/scvae_wo_activities")
a = p.parse_args()
t0 = time.time()
run = load_run(a.run_dir)
trained = infer.load(run)
fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
scorer, gate = load_gate(run.run_dir)


def records(split):
    w = load_dataset("cmu", split, window=65, offset=20)
    out = []
    for n in (10, 30, 50):
        k0, k1 = 9, 10 + n
        keys = (w.local_quats[:, k0], w.root_pos[:, k0], w.local_quats[:, k1], w.root_pos[:, k1])
        s = infer.sample_transitions(trained.cfg.model, trained.state, w, 10, n, 4, sampled=False)
        bq, br = slerp_base(*keys, n)
        base = per_frame_error(w, 10, n, bq[None], br[None])[0].mean(-1)
        at = np.stack([per_frame_error(w, 10, n, *gate_blend(s["q"], s["r"], bq, br, np.full(len(w), x)))
                       .mean((0, 2)) for x in BLEND_WEIGHTS], 1) / np.maximum(base, 1e-6)[:, None]
        mis = np.linalg.norm(s["mid_f"] - s["mid_b"], axis=-1).mean((0, 2))          # (B,) cm
        travel = scorer.score(keyframe_context(*keys, n, w.skeleton, fa))
        for i, name in enumerate(w.seq_names):
            out.append({"group": f"{activity_group(name.split('@')[0])}/{n}", "at": at[i], "mis": mis[i],
                        "mis_rel": mis[i] / max(base[i], 1e-6), "travel": travel[i],
                        "travel_w": float(gate.weight(travel[i]))})
    return out


def summary(recs, weight):
    r = gated_ratio([x["at"] for x in recs], weight)
    groups = collections.defaultdict(list)
    for x, ri in zip(recs, r):
        groups[x["group"]].append(ri)
    worst = max(groups, key=lambda g: np.mean(groups[g]))
    return (f"mean {r.mean():.3f}, p90 {np.quantile(r, 0.9):.3f}, max {r.max():.2f}, worst group {worst} "
            f"{np.mean(groups[worst]):.3f}")


sets = {"val-subjects": records("val-subjects"), "val-activities": records("val-activities")}
val = sets["val-subjects"]
print(f"{a.run_dir}: {len(val)} / {len(sets['val-activities'])} windows, {time.time() - t0:.0f} s")
for name, recs in sets.items():
    tw = np.array([x["travel_w"] for x in recs])
    print(f"{name}: network alone: {summary(recs, np.ones(len(recs)))}\n  travel gate: {summary(recs, tw)}")
    for key in ("mis", "mis_rel"):
        v = np.array([x[key] for x in recs])
        print(f"  {key}: median {np.median(v):.2f}, p90 {np.quantile(v, 0.9):.2f}")
for key in ("mis", "mis_rel"):
    v = np.array([x[key] for x in val])
    rule = calibrate_gate(v, [x["at"] for x in val], groups=[x["group"] for x in val],
                          scale=np.array([x["travel_w"] for x in val]))[0]
    for label, cap in (("the gate's rule", rule), ("quantiles 0.9 / max", Gate(float(np.quantile(v, 0.9)),
                                                                               float(v.max())))):
        print(f"cap on {key}, {label} on val-subjects ({cap.lo:.3f} / {cap.hi:.3f}):")
        for name, recs in sets.items():
            w = np.minimum([x["travel_w"] for x in recs], cap.weight([x[key] for x in recs]))
            print(f"  {name}: {summary(recs, w)}")
both = val + sets["val-activities"]
g, s = calibrate_gate([x["travel"] for x in both], [x["at"] for x in both], groups=[x["group"] for x in both])
print(f"travel gate re-chosen on both splits: {g.lo:.3f} / {g.hi:.3f}, meets the limits: {s['meets_limits']}")
for name, recs in sets.items():
    print(f"  {name}: {summary(recs, g.weight([x['travel'] for x in recs]))}")
