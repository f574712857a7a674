"""Inside a clip the frames beside the keyframes are known (``inbetween infill``): should the S-CVAE's fill follow the
Hermite path through them (``model.context_base``, :mod:`inbetween_jax.models.scvae.context`) instead of Slerp,
and with which damping (``model.context_damping``)?

Gaps every ``--stride`` frames (from frame ``--first``, default 3: CMU files often begin with capture start-up
frames; the run's caps on the neighbours' velocity apply unless ``--no-cap``) in the ``cmu``
source's validation subjects (``--split val-subjects``, the default: choose here), the subjects a run trained on
``train.split=fit-activities`` never saw (``--split val-activities``) or the test subjects (``--split
test``, the embedded 13 / 14 files: look once, at the end), read as training reads them (the 21-joint body, 30
fps).  Per gap, one sample (the deterministic fill) through :func:`~inbetween_jax.models.scvae.infer.infill_between`
with the frames beside the keyframes, as ``inbetween infill`` passes them.  Candidates, each as mean joint position
error (FK on the run's rig) over Slerp / lerp's:

* ``fill (Slerp)``: the run's fill as configured, context off (the shipped behaviour before);
* ``hermite dD``: the Hermite path alone, damping D (no network);
* ``fill (hermite dD)``: the run's fill with ``model.context_base`` and damping D.

The rule, fixed before the runs: the lowest mean among the candidates whose pooled 90th percentile is at most
1.05x, worst gap at most 1.5x and every (activity group, length) mean at most 1.00x.

With ``--sample-weights W,...`` it instead scores the sampled mode inside a clip (``model.bank_sample_weight``,
10 samples, the run's context switches): per weight, mean-of-10 and best-of-10 error over Slerp's, and how far
apart the samples are (mean pairwise per-joint distance over Slerp's error, as a mean of per-gap ratios and as a
ratio of means).  The rule, as for the weight shipped first: the largest weight whose mean-of-10 stays within 3 %
of sample 0's (the deterministic fill) in every (activity group, length).

    python experiments/scvae_context_base.py [--split val-subjects|test] [--run RUN_DIR] [--damping 0,0.05,0.1]
    python experiments/scvae_context_base.py --sample-weights 0.15,0.25,0.35
"""
import argparse
import dataclasses
import os

import numpy as np

from inbetween_jax.data.activities import activity_group
from inbetween_jax.data.datasets import split_files
from inbetween_jax.data.files import embedded_files
from inbetween_jax.data.sources import cmu_train_plan, read_cmu_train, val_files
from inbetween_jax.evaluation.worst_case import summarise
from inbetween_jax.geometry import quat_mul
from inbetween_jax.models.scvae import infer as scvae
from inbetween_jax.models.scvae.context import clip_keyframes, context_offsets, known_sides, neighbours
from inbetween_jax.models.scvae.gate import slerp_base
from inbetween_jax.shipped import shipped_run
from inbetween_jax.train.config import apply_overrides
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--split", default="val-subjects", choices=["val-subjects", "val-activities", "test"],
               help="val-activities: the subjects a run trained on fit-activities never saw (sports, dance, karate)")
p.add_argument("--run", default=None, help="run folder (default: the shipped weights)")
p.add_argument("--frames", default="10,30,50")
p.add_argument("--damping", default="0,0.05,0.1,0.15,0.2")
p.add_argument("--stride", type=int, default=45)
p.add_argument("--sample-weights", default=None, help="score the sampled mode at these model.bank_sample_weight")
p.add_argument("--first", type=int, default=3, help="first start keyframe of a file (1: from its second frame)")
p.add_argument("--no-cap", action="store_true", help="model.context_max_turn = context_max_step = 0")
p.add_argument("--set", action="append", default=[], metavar="model.KEY=VALUE", help="an inference switch, e.g. "
               "model.ood_gate=true for a run folder whose config has it off")
a = p.parse_args()
run = load_run(a.run) if a.run else shipped_run("scvae")
trained = scvae.load(run)
caps = ["model.context_max_turn=0", "model.context_max_step=0"] if a.no_cap else []
trained = dataclasses.replace(trained, cfg=apply_overrides(trained.cfg, caps + a.set))
if trained.cfg.model.ood_gate and trained.gate is None:          # switched on here: the run folder's ood.npz
    from inbetween_jax.models.ood import run_gate
    trained = dataclasses.replace(trained, gate=run_gate(run.run_dir, True))
dampings = [float(x) for x in a.damping.split(",")]


def switched(**kw):
    return dataclasses.replace(trained, cfg=dataclasses.replace(trained.cfg, model=dataclasses.replace(
        trained.cfg.model, **kw)))


if a.sample_weights:
    weights = [float(x) for x in a.sample_weights.split(",")]
    variants = {f"w {w:g}{' gated' if g else ''}": switched(bank_sample_weight=w, bank_sample_gated=g)
                for w in weights for g in (False, True)}
    dampings, num_samples = [], 10
else:
    variants = {"fill (Slerp)": switched(context_base=False),
                **{f"fill (hermite d{d:g})": switched(context_base=True, context_damping=d) for d in dampings}}
    num_samples = 1
fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
files = (val_files(cmu_train_plan()[0], by="subject") if a.split == "val-subjects" else embedded_files("test")
         if a.split == "test" else split_files("cmu", a.split))
motions = read_cmu_train(files, a.split, run.fps)[0]


rows = []           # (group, n, {candidate: ratio to Slerp})
for path, m in zip(files, motions):
    gp = m.positions_of(m.local_quats, m.root_pos)
    group = activity_group(path)
    for n in [int(x) for x in a.frames.split(",")]:
        for k0 in range(a.first, m.num_frames - n - 2, a.stride):
            k1 = k0 + n + 1
            err = lambda q, r: np.linalg.norm(m.positions_of(q, r) - gp[k0 + 1:k1], axis=-1).mean()  # noqa: E731
            s, e = clip_keyframes(m, k0, k1)                 # as inbetween infill passes them
            keys = [x[k][None] for x, k in ((m.local_quats, k0), (m.root_pos, k0), (m.local_quats, k1),
                                            (m.root_pos, k1))]
            sq, sr = slerp_base(*keys, n)
            res = {}
            for d in dampings:
                nb = neighbours(trained.cfg.model, m.skeleton, *keys, *known_sides(s, e))
                dq, dr = context_offsets(*keys, n, d, *nb)
                res[f"hermite d{d:g}"] = err(quat_mul(sq[0], dq[0]), sr[0] + dr[0])
            for name, t in variants.items():
                out = scvae.infill_between(t, m.skeleton, s, e, n, num_samples, 0, fa)
                each = [err(q, r) for q, r in zip(out["q"][:, 1:-1], out["r"][:, 1:-1])]
                res[name] = np.mean(each)
                if num_samples > 1:
                    pos = m.positions_of(out["q"][:, 1:-1], out["r"][:, 1:-1])
                    i, j = np.triu_indices(num_samples, 1)
                    res.update({f"{name} sample 0": each[0], f"{name} best": min(each),
                                f"{name} apart": np.linalg.norm(pos[i] - pos[j], axis=-1).mean()})
            rows.append((group, n, {k: v / err(sq[0], sr[0]) for k, v in res.items()}, err(sq[0], sr[0]),
                         f"{os.path.basename(path)}:{k0}"))

if a.sample_weights:
    print(f"{a.split}: {len(rows)} gaps; sampled mode inside a clip, 10 samples; errors over Slerp's")
    print("| weight | mean of 10 | sample 0 | worst (group, length) mean of 10 / sample 0 | best of 10 | apart "
          "(mean of ratios) | apart (ratio of means) | meets the rule |")
    print("|---|---|---|---|---|---|---|---|")
    slerp_mean = np.mean([r[3] for r in rows])
    for name in variants:
        per = [(np.mean([r[2][name] for r in rows if (r[0], r[1]) == g])
                / np.mean([r[2][f"{name} sample 0"] for r in rows if (r[0], r[1]) == g]), g)
               for g in sorted({(r[0], r[1]) for r in rows})]
        worst = max(per)
        apart = np.mean([r[2][f"{name} apart"] for r in rows])
        ratio_of_means = np.mean([r[2][f"{name} apart"] * r[3] for r in rows]) / slerp_mean
        print(f"| {name} | {np.mean([r[2][name] for r in rows]):.3f} | "
              f"{np.mean([r[2][name + ' sample 0'] for r in rows]):.3f} | {worst[0]:.3f} ({worst[1][0]}, "
              f"{worst[1][1]}) | {np.mean([r[2][name + ' best'] for r in rows]):.3f} | {apart:.3f} | "
              f"{ratio_of_means:.3f} | {'yes' if worst[0] <= 1.03 else 'no'} |")
    raise SystemExit(0)

names = list(rows[0][2])
groups = sorted({(r[0], r[1]) for r in rows})
print(f"{a.split}: {len(rows)} gaps ({len(files)} files); per-gap error / Slerp's")
print("| candidate | mean | p90 | max | share > 1.10x | worst (group, length) mean | meets the rule |")
print("|---|---|---|---|---|---|---|")
ok = {}
for k in names:
    s = summarise([r[2][k] for r in rows])
    worst = max((np.mean([r[2][k] for r in rows if (r[0], r[1]) == g]), g) for g in groups)
    ok[k] = s["p90"] <= 1.05 and s["max"] <= 1.5 and worst[0] <= 1.0 + 1e-9
    print(f"| {k} | {s['mean']:.3f} | {s['p90']:.3f} | {s['max']:.3f} | {100 * s['share_worse_10pct']:.0f} % | "
          f"{worst[0]:.3f} ({worst[1][0]}, {worst[1][1]}) | {'yes' if ok[k] else 'no'} |")
print("\nper activity group and length, mean (p90, max):")
for g in groups:
    sel = [r[2] for r in rows if (r[0], r[1]) == g]
    print(f"  {g[0]:8s} {g[1]:3d} ({len(sel):3d}): " + " | ".join(
        f"{k} {np.mean([x[k] for x in sel]):.3f} ({summarise([x[k] for x in sel])['p90']:.2f}, "
        f"{max(x[k] for x in sel):.2f})" for k in names if k.startswith("fill")))
worst = sorted(rows, key=lambda r: -r[2][names[-1]])[:6]
print(f"\nworst gaps of {names[-1]}: " + ", ".join(f"{r[4]} ({r[1]} frames) {r[2][names[-1]]:.2f}" for r in worst))
best = min((k for k in names if k.startswith("fill") and ok[k]), default=None,
           key=lambda k: summarise([r[2][k] for r in rows])["mean"])
print(f"\nchosen by the rule: {best}")
