"""The CAE's base in global positions where the body stays near its place (``model.global_base_near`` / ``_far`` /
``_fade``, :mod:`inbetween_jax.models.cae.global_base`), against the body-frame base the gate fell back to before
(``model.base_edge_fade`` on the joints, the root on its edge-faded Hermite path) and against straight lines between
the global joint positions beside the gap.  No network and no bank take part, so the fit subjects' files may judge
a base as the validation subjects do.

Per set and gap length (0.5, 1 and 2 s, every ``max(g, 30)`` frames as the bench's in-file rows): the mean error over
the body-frame base's, its 90th percentile and maximum, the worst activity group (at least 3 gaps, 1 and 2 s), and
the error over straight lines (mean / p90 / max, and how many gaps are more than 1.5x worse than the lines).
A rule ``NEAR:FAR`` (metres) gives the global fill the whole base where the root is expected to travel at most NEAR
across the gap (floor speed beside it x its frames), none from FAR.

    python experiments/cae_global_base.py inbetween_jax/assets/weights/cae [--fades 0.2,0.3] [--rules 0.4:0.8,...]
                                          [--splits val-subjects,fit-subjects | --files F.bvh ...]     # ~2 min
"""
import argparse
import collections
import dataclasses

import numpy as np

from inbetween_jax.data import load_motions, read_bvh
from inbetween_jax.data.activities import activity_group
from inbetween_jax.data.retarget import prepare
from inbetween_jax.models.cae.features import body_frame_features
from inbetween_jax.models.cae.global_base import base_positions, global_fill, travel_share
from inbetween_jax.models.cae.in_file import gap_starts
from inbetween_jax.models.cae.infer import load
from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--fades", default="0.2,0.3,0.4")
p.add_argument("--rules", default="0.3:0.6,0.4:0.8,0.5:1.0,0.6:1.2,1e6:2e6",
               help="NEAR:FAR in metres; 1e6:2e6 is the global fill everywhere")
p.add_argument("--splits", default="val-subjects,fit-subjects")
p.add_argument("--files", nargs="+", default=None, help="BVH files instead of the splits")
p.add_argument("--seconds", default="0.5,1,2")
a = p.parse_args()
run = load_run(a.run_dir)
model = load(run)
body_model = dataclasses.replace(model.cfg.model, global_base_far=0.0)
model.cfg = dataclasses.replace(model.cfg, model=body_model)                 # base_positions: the body-frame base
fades = [float(f) for f in a.fades.split(",")]
rules = [tuple(float(v) for v in r.split(":")) for r in a.rules.split(",")]
if a.files:
    sets = {"files": [prepare(read_bvh(f), f, model.skeleton, run.fps).motion for f in a.files]}
else:
    sets = {s: load_motions("cmu", s) for s in a.splits.split(",")}
err = collections.defaultdict(list)          # (set, fade, rule) -> [(sec, group, over body base, over lines)]
for name, motions in sets.items():
    for sec in [float(s) for s in a.seconds.split(",")]:
        for m in motions:
            g = int(round(sec * float(m.fps)))
            for lo in gap_starts(m.num_frames, g):
                fm = gap_frames(m.num_frames, [(lo, lo + g)])
                feats = body_frame_features(m, known=fm > 0.5)
                mask = frame_mask_image(fm, model.num_joints)
                xm = model.normalizer(feats.features).T.astype(np.float32) * mask
                truth = feats.global_pos[lo:lo + g]
                body = base_positions(model, xm, mask, feats, fm)[lo:lo + g]
                w = (np.arange(1, g + 1) / (g + 1))[:, None, None]
                lines = feats.global_pos[lo - 1] + w * (feats.global_pos[lo + g] - feats.global_pos[lo - 1])
                e_body = np.linalg.norm(body - truth, axis=-1).mean()
                e_lines = np.linalg.norm(lines - truth, axis=-1).mean()
                group = activity_group(str(m.source))
                err[(name, -1.0, (0.0, 0.0))].append((sec, group, 1.0, e_body / max(e_lines, 1e-9)))
                for fade in fades:
                    glob = global_fill(feats.global_pos, fm, fade)[lo:lo + g]
                    for near, far in rules:
                        s = travel_share(feats.ref, lo, lo + g, near, far)
                        e = np.linalg.norm(body + s * (glob - body) - truth, axis=-1).mean()
                        err[(name, fade, (near, far))].append((sec, group, e / max(e_body, 1e-9),
                                                               e / max(e_lines, 1e-9)))
        print(f"{name}: {sec} s done", flush=True)
print("| set | fade | rule NEAR:FAR (m) | over the body-frame base: mean (each length, shortest first), p90, max | worst group "
      "(1-2 s) | over straight lines: mean / p90 / max, gaps > 1.5x |")
print("|---|---|---|---|---|---|")
for (name, fade, rule), rows in sorted(err.items()):
    xb = np.array([r[2] for r in rows])
    xl = np.array([r[3] for r in rows])
    per = " / ".join(f"{np.mean([r[2] for r in rows if r[0] == s]):.3f}" for s in sorted({r[0] for r in rows}))
    groups = collections.defaultdict(list)
    for r in rows:
        if r[0] >= 1:
            groups[(r[1], r[0])].append(r[2])
    worst = max(((np.mean(v), k) for k, v in groups.items() if len(v) >= 3), default=(float("nan"), ("-", 0)))
    label = "global everywhere" if rule[0] >= 1e5 else f"{rule[0]:g}:{rule[1]:g}"
    if fade < 0:
        print(f"| {name} | - | body-frame base (shipped before) | 1 | - | {xl.mean():.3f} / {np.quantile(xl, 0.9):.3f} "
              f"/ {xl.max():.2f}, {int((xl > 1.5).sum())} |")
        continue
    print(f"| {name} | {fade:g} | {label} | {xb.mean():.4f} ({per}), {np.quantile(xb, 0.9):.3f}, {xb.max():.2f} | "
          f"{worst[1][0]}/{worst[1][1]:g} s {worst[0]:.3f} | {xl.mean():.3f} / {np.quantile(xl, 0.9):.3f} / "
          f"{xl.max():.2f}, {int((xl > 1.5).sum())} |")
