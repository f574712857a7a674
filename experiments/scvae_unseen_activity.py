"""Does the S-CVAE's gate protect an activity the network never saw?  A run trained on ``train.split=fit-activities``
(no sports, Indian dance or karate subjects) scored inside a clip, as ``inbetween infill`` fills, on those subjects'
files (``--split val-activities``) or on the validation subjects (``--split val-subjects``, people never trained on
doing covered activities).

Per gap (every 45 frames, 10 / 30 / 50 frames, the frames beside the keyframes passed as ``infill`` passes
them, the run's context switches): the fill at each learned-fill weight of
:data:`~inbetween_jax.models.ood.BLEND_WEIGHTS` (weight 0: the base, the Hermite path through the neighbours),
its error over the base's and over Slerp's, and the two scores a gate could read: the travel score (the shipped
gate's, :class:`~inbetween_jax.models.ood.TravelScore`) and the k-NN distance of the keyframe context to the
run's training contexts (:class:`~inbetween_jax.models.ood.ContextBank`, as ``calibrate-gate --kind knn`` builds
it).  Then the error over the base per group at the run's own gate, and at the run's gate combined with a k-NN
gate whose thresholds are quantiles of the validation subjects' k-NN scores (``--json`` of a
``--split val-subjects`` pass, ``--knn-from``): the learned fill is kept only where the keyframes look like the
motion of people the network generalises to.

    python experiments/scvae_unseen_activity.py --run RUN --split val-subjects --json vs.json
    python experiments/scvae_unseen_activity.py --run RUN --split val-activities --knn-from vs.json
"""
import argparse
import json

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.evaluation.worst_case import summarise
from inbetween_jax.models.ood import Gate, gated_ratio, load_gate
from inbetween_jax.models.scvae import infer as scvae
from inbetween_jax.models.scvae.calibrate import in_clip_records
from inbetween_jax.models.scvae.gate import context_gate, training_bank
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--run", required=True)
p.add_argument("--split", default="val-activities", choices=["val-activities", "val-subjects", "test"])
p.add_argument("--json", default=None, help="write the per-gap records here")
p.add_argument("--knn-from", default=None, help="records of a val-subjects pass: k-NN thresholds from their scores")
p.add_argument("--quantiles", default="0.9:1.0,0.95:1.0,0.99:1.0,1.0:1.0")
a = p.parse_args()
run = load_run(a.run)
trained = scvae.load(run)
scorer, own = load_gate(run.run_dir)
inside = context_gate(run.run_dir)
fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
bank = training_bank(run.data.get("source", "cmu"), run.config["train"]["split"], fa)
records = in_clip_records(trained, load_motions("cmu", a.split), fa, scorer=scorer, knn=bank)
for r in records:
    r["group"] = activity_group(r["name"].rsplit(":", 1)[0])
if a.json:
    with open(a.json, "w") as f:
        json.dump({"run": a.run, "split": a.split, "records": records}, f)

ratios_at = [r["ratios_at"] for r in records]
gates = {"network alone (weight 1)": np.ones(len(records)),
         "the run's two-keyframe gate (travel)": own.weight([r["score"] for r in records])}
if inside is not None:
    gates["the run's gate inside a clip (travel)"] = inside.weight([r["score"] for r in records])
if a.knn_from:
    familiar = np.array([r["knn_score"] for r in json.load(open(a.knn_from))["records"]])
    for spec in a.quantiles.split(","):
        lo_q, hi_q = (float(x) for x in spec.split(":"))
        lo, hi = np.quantile(familiar, lo_q), np.quantile(familiar, hi_q)
        kg = Gate(float(lo), float(max(hi, lo + 1e-6)))
        gates[f"two-keyframe gate and k-NN ({lo_q:g} / {hi_q:g} quantile: {lo:.3f} / {hi:.3f})"] = np.minimum(
            gates["the run's two-keyframe gate (travel)"], kg.weight([r["knn_score"] for r in records]))
print(f"{a.run}: {a.split}, {len(records)} gaps; error over the base (the Hermite path through the neighbours); "
      f"the base over Slerp: {np.mean([r['base_x_slerp'] for r in records]):.3f}")
print(f"k-NN score: median {np.median([r['knn_score'] for r in records]):.3f}, "
      f"p90 {np.quantile([r['knn_score'] for r in records], 0.9):.3f}")
groups = sorted({(r["group"], r["frames"]) for r in records})
print("| gate | mean | p90 | max | share > 1.10x | kept weight | worst (group, length) | " +
      " | ".join(f"{g} {n}" for g, n in groups) + " |")
print("|---|---|---|---|---|---|---|" + "---|" * len(groups))
for name, w in gates.items():
    rat = gated_ratio(ratios_at, w)
    s = summarise(rat)
    per = [float(np.mean([x for x, r in zip(rat, records) if (r["group"], r["frames"]) == g])) for g in groups]
    worst = int(np.argmax(per))
    print(f"| {name} | {s['mean']:.3f} | {s['p90']:.3f} | {s['max']:.3f} | {100 * s['share_worse_10pct']:.0f} % | "
          f"{np.mean(w):.2f} | {per[worst]:.3f} ({groups[worst][0]}, {groups[worst][1]}) | " +
          " | ".join(f"{x:.3f}" for x in per) + " |")
