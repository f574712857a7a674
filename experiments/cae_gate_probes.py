"""Probes behind the CAE's floor-speed gate (docs/results/gate.md, "The CAE's network now learns"), on the
validation subjects only.

    python experiments/cae_gate_probes.py RUN_DIR calibration      # per group: network alone, floor speed, k-NN score
    python experiments/cae_gate_probes.py RUN_DIR dropout          # joint recovery: network, gated, pre-fill, linear
    python experiments/cae_gate_probes.py RUN_DIR smooth [--sigmas 0,1,2,3]   # the residual smoothed over time

``calibration`` reads the run's ``ood_calibration.json`` (``inbetween calibrate-gate``, which records both scores
per gap).  ``dropout`` scores the validation clips with joints dropped at p = 0.3 / 0.5 (the bench's Table 2
corruption), the network's fill without the gate against the gated fill, which keeps the pre-fill there.
``smooth`` blurs the network's residual over its pre-fill with a Gaussian of ``sigma`` frames before the gate and
scores the in-file gaps (:func:`inbetween_jax.models.cae.in_file.gap_records`) and the foot lift-offs of 2 and 4 s
gaps in the walking files against the capture's.
"""
import argparse
import collections
import json
import os

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.models.cae.infer import load
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("what", choices=("calibration", "dropout", "smooth"))
p.add_argument("--sigmas", default="0,1,2,3")
a = p.parse_args()


def calibration():
    with open(os.path.join(a.run_dir, "ood_calibration.json")) as f:
        cal = json.load(f)
    groups = collections.defaultdict(list)
    for r in cal["records"]:
        groups[(activity_group(r["name"]), r["frames"])].append((r["ratios_at"][-1], r["floor_speed"], r["knn_score"]))
    print(f"gate kind {cal['summary'].get('kind')}, lo {cal['summary']['lo']:.4f} / hi {cal['summary']['hi']:.4f}")
    print("| group | frames | gaps | network alone / pre-fill | floor speed (median, range; units per frame) | "
          "k-NN score (median) |\n|---|---|---|---|---|---|")
    for (g, n), v in sorted(groups.items()):
        v = np.array(v)
        print(f"| {g} | {n} | {len(v)} | {v[:, 0].mean():.3f} | {np.median(v[:, 1]):.2f} ({v[:, 1].min():.2f}-"
              f"{v[:, 1].max():.2f}) | {np.median(v[:, 2]):.2f} |")


def dropout(model):
    from inbetween_jax.baselines import linear_fill
    from inbetween_jax.evaluation import infilling as proto
    from inbetween_jax.models.cae.gate import base_fill
    from inbetween_jax.models.cae.infer import fill
    x = proto.test_clips(load_motions("cmu", "val-subjects"), model.normalizer, 96, 48)
    corrupt = proto.corruptions(x, model.num_joints)
    print("| p | network (no gate) | gated (shipped) | pre-fill | linear fill |\n|---|---|---|---|---|")
    for k in (f"p={q}" for q in proto.PS):
        inp, m = corrupt[k]
        cm = [proto.position_error(y, x, model.normalizer, model.num_joints)[0]
              for y in (fill(model, inp, m, gate=False), fill(model, inp, m), base_fill(model, inp, m),
                        np.asarray(linear_fill(inp * m, m)))]
        print(f"| {k[2:]} | " + " | ".join(f"{c:.3f} cm" for c in cm) + " |")


def smooth(model):
    import inbetween_jax.models.cae.gate as gate_module
    from inbetween_jax.geometry import forward_kinematics
    from inbetween_jax.metrics.steps import lift_offs
    from inbetween_jax.models.cae.in_file import gap_records, gap_starts
    from inbetween_jax.models.cae.infer import process_motion
    plain, sigma = gate_module.gate_clips, [0.0]

    def blurred(r):                                   # Gaussian of sigma[0] frames along the last axis, zero-padded
        s = sigma[0]
        k = np.arange(-int(3 * s + 1), int(3 * s + 1) + 1)
        w = np.exp(-0.5 * (k / s) ** 2)
        w /= w.sum()
        pad = np.pad(r, [(0, 0)] * (r.ndim - 1) + [(len(k) // 2,) * 2]).reshape(-1, r.shape[-1] + len(k) - 1)
        return np.stack([np.convolve(row, w, mode="valid") for row in pad]).reshape(r.shape)

    def smoothed_gate(model_, x_masked, mask, y):     # process_motion imports gate_clips from the module per call
        if sigma[0] > 0:
            m = np.broadcast_to(np.asarray(mask, np.float32), np.shape(y))
            base = gate_module.base_fill(model_, x_masked, m)
            y = np.where(m > 0.5, y, base + blurred(np.where(m > 0.5, 0.0, np.asarray(y) - base))).astype(np.float32)
        return plain(model_, x_masked, mask, y)
    gate_module.gate_clips = smoothed_gate
    motions = load_motions("cmu", "val-subjects")
    feet = model.skeleton.foot_joints()
    for s in [float(v) for v in a.sigmas.split(",")]:
        sigma[0] = s
        r = np.array([x["ratio"] for x in gap_records(model, motions)])
        lifts = []
        for m in (m for m in motions if activity_group(str(m.source)) == "walk"):
            gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
            for g in (int(round(2 * m.fps)), int(round(4 * m.fps))):
                for lo in gap_starts(m.num_frames, g):
                    span = slice(lo - 1, lo + g + 1)
                    pos = process_motion(model, m, [(lo, lo + g)])["positions"]
                    lifts.append((float(lift_offs(pos[span], (feet[0], feet[2]))),
                                  float(lift_offs(gp[span], (feet[0], feet[2])))))
        lifts = np.array(lifts)
        print(f"sigma {s:g}: in-file gaps {len(r)}, mean {r.mean():.4f}, p90 {np.quantile(r, 0.9):.3f}, max "
              f"{r.max():.3f} (x the Hermite fill); walking 2-4 s gaps {len(lifts)}: lift-offs {lifts[:, 0].mean():.2f}"
              f", capture {lifts[:, 1].mean():.2f}", flush=True)


if a.what == "calibration":
    calibration()
else:
    (dropout if a.what == "dropout" else smooth)(load(load_run(a.run_dir)))
