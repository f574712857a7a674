"""Should the S-CVAE's in-clip gate have thresholds per gap length?  Calibrated per length on the run's own
validation gaps (``ood_calibration.json``'s ``context_records``, by :func:`~inbetween_jax.models.ood.calibrate_gate`'s
rule), against the run's one pair of thresholds, and both scored on gaps of a held-out split the calibration never
saw (:func:`~inbetween_jax.models.scvae.calibrate.in_clip_records`, about 3 min for ``val-activities``).

    python experiments/scvae_in_clip_gate_lengths.py [RUN_DIR] [--split val-activities]

Default RUN_DIR: ``runs/scvae_wo_activities`` (trained on ``train.split=fit-activities``; its ``val-activities``
subjects and activities were held out of training and of the calibration).  Prints, per length, each gate's
thresholds and its error over the Hermite path on the calibration gaps and on the held-out ones (mean, p90, max,
per activity group).
"""
import argparse
import json
import os
import time

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.models.ood import calibrate_gate, gated_ratio, Gate
from inbetween_jax.models.ood_runs import CALIBRATION_FILE
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.calibrate import in_clip_records
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir", nargs="?", default="runs/scvae_wo_activities")
p.add_argument("--split", default="val-activities")
a = p.parse_args()
t0 = time.time()
with open(os.path.join(a.run_dir, CALIBRATION_FILE)) as f:
    cal = json.load(f)
own, summary = cal["context_records"], cal["summary"]
trained = infer.load(load_run(a.run_dir))
fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
held = in_clip_records(trained, load_motions("cmu", a.split), fa)


def scored(records, gate):
    s = np.array([r["score"] for r in records])
    return gated_ratio([r["ratios_at"] for r in records], gate.weight(s))


def line(records, gate):
    x = scored(records, gate)
    groups = {}
    for r, v in zip(records, x):
        groups.setdefault(activity_group(r["name"]), []).append(v)
    per = ", ".join(f"{g} {np.mean(v):.3f}" for g, v in sorted(groups.items()))
    return f"{x.mean():.3f} / {np.quantile(x, 0.9):.3f} / {x.max():.3f} ({per})"


print(f"| frames | gate | lo / hi | calibration gaps: mean / p90 / max | {a.split}: mean / p90 / max (groups) |")
print("|---|---|---|---|---|")
one = Gate(summary["context_lo"], summary["context_hi"])
for n in sorted({r["frames"] for r in own}):
    mine, theirs = [r for r in own if r["frames"] == n], [r for r in held if r["frames"] == n]
    per_length = calibrate_gate([r["score"] for r in mine], [r["ratios_at"] for r in mine],
                                groups=[f"{activity_group(r['name'])}/{n}" for r in mine])[0]
    for name, gate in (("one pair (shipped rule)", one), ("per length", per_length)):
        print(f"| {n} ({len(mine)} / {len(theirs)}) | {name} | {gate.lo:.3f} / {gate.hi:.3f} | {line(mine, gate)} | "
              f"{line(theirs, gate)} |")
print(f"({time.time() - t0:.0f} s)")
