"""Does the CAE's gate protect an activity the network never saw?  A run trained on ``train.split=fit-activities``
(no sports, Indian dance or karate subjects) scored by its gate's calibration protocol (gaps of 1 and 2 s in 96-frame
clips, body-frame joint error over the Hermite pre-fill's at each learned-fill weight,
:func:`inbetween_jax.models.cae.calibrate.calibrate`) on the validation subjects and on those subjects' files
(``val-activities``).  Per split and activity group: the error over the pre-fill with the network alone, at the
run's own gate (the root's floor speed beside the gap), and at that gate combined with a k-NN gate (the gap context's
distance to the run's training contexts) whose thresholds are quantiles of the validation subjects' k-NN scores.

    python experiments/cae_unseen_activity.py RUN_DIR [--quantiles 0.9:1.0,0.99:1.0]
"""
import argparse

import numpy as np

from inbetween_jax.data.activities import activity_group
from inbetween_jax.evaluation.worst_case import summarise
from inbetween_jax.models.cae.calibrate import calibrate
from inbetween_jax.models.ood import Gate, gated_ratio, load_gate
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--quantiles", default="0.9:1.0,0.95:1.0,0.99:1.0,1.0:1.0")
a = p.parse_args()
run = load_run(a.run_dir)
scorer, own = load_gate(a.run_dir)
sets = {s: calibrate(run, run.data.get("source", "cmu"), split=s)["records"] for s in ("val-subjects", "val-activities")}
familiar = np.array([r["knn_score"] for r in sets["val-subjects"]])
for split, recs in sets.items():
    floor = own.weight(scorer.score_of_speed([r["floor_speed"] for r in recs]))
    gates = {"network alone (weight 1)": np.ones(len(recs)), "the run's gate (floor speed)": floor}
    for spec in a.quantiles.split(","):
        lo_q, hi_q = (float(x) for x in spec.split(":"))
        lo, hi = np.quantile(familiar, lo_q), np.quantile(familiar, hi_q)
        kg = Gate(float(lo), float(max(hi, lo + 1e-6)))
        gates[f"floor speed and k-NN ({lo_q:g} / {hi_q:g} quantile: {lo:.3f} / {hi:.3f})"] = np.minimum(
            floor, kg.weight([r["knn_score"] for r in recs]))
    groups = sorted({(activity_group(r["name"]), r["frames"]) for r in recs})
    print(f"\n{a.run_dir}: {split}, {len(recs)} gaps; error over the Hermite pre-fill; k-NN score median "
          f"{np.median([r['knn_score'] for r in recs]):.3f}, floor speed median "
          f"{np.median([r['floor_speed'] for r in recs]):.2f} cm/frame")
    print("| gate | mean | p90 | max | share > 1.10x | kept weight | " + " | ".join(f"{g} {n}" for g, n in groups) + " |")
    print("|---|---|---|---|---|---|" + "---|" * len(groups))
    for name, w in gates.items():
        rat = gated_ratio([r["ratios_at"] for r in recs], w)
        s = summarise(rat)
        per = [np.mean([x for x, r in zip(rat, recs) if (activity_group(r["name"]), r["frames"]) == g])
               for g in groups]
        print(f"| {name} | {s['mean']:.3f} | {s['p90']:.3f} | {s['max']:.3f} | "
              f"{100 * s['share_worse_10pct']:.0f} % | {np.mean(w):.2f} | " + " | ".join(f"{x:.3f}" for x in per) + " |")
