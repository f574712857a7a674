"""Other non-learned fills for the CAE's gaps inside a file, against the shipped base (the limited cubic Hermite),
judged on the validation subjects and on the fit subjects' files: no network and no bank take part, so every file
the training saw may score them.

Where the gate shuts (most gaps), the CAE's fill is its Hermite base.  Each variant here changes the base's body
pose in the gap (the body-frame joint positions; the root keeps the Hermite root path, as ``model.root_bound``
holds it):

* ``limit L``: the Hermite's tangent limiter at L times the secant slope (the shipped 3; 0 is a smoothstep
  between the edges, with no edge velocity);
* ``pull B / W``: the pose pulled toward the mean of the known frames within W frames of each edge, by
  ``B sin(pi s)`` at gap phase s (0 at both edges, B mid-gap).  For motion that oscillates faster than the gap
  (jumps in place, dance steps), the mean pose is the smallest-error guess for a phase nobody knows.

Printed: per set and (activity group, gap length), the mean error over the shipped base's, and the pooled mean /
p90 / max, for every variant.

    python experiments/cae_base_probe.py inbetween_jax/assets/weights/cae        # about 3 min
"""
import argparse
import collections

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.models.cae.features import body_frame_features
from inbetween_jax.models.cae.gate import base_fill
from inbetween_jax.models.cae.in_file import gap_positions, gap_starts
from inbetween_jax.models.cae.infer import load
from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
from inbetween_jax.baselines import hermite_fill
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--limits", default="3,1.5,1,0.5,0")
p.add_argument("--pulls", default="0.25,0.5,0.75,1.0")
p.add_argument("--windows", default="8,15,30")
a = p.parse_args()
model = load(load_run(a.run_dir))
j = model.num_joints
limits = [float(v) for v in a.limits.split(",")]
pulls = [float(v) for v in a.pulls.split(",")]
windows = [int(v) for v in a.windows.split(",")]
names = [f"limit {v:g}" for v in limits] + [f"pull {b:g} / {w}" for b in pulls for w in windows]
pos_rows = slice(0, 3 * j)                       # body-frame joint positions; the last three rows: root velocities

recs = []
for set_name, split in (("validation", "val-subjects"), ("fit", "fit-subjects")):
    for m in load_motions("cmu", split):
        gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
        group = activity_group(str(m.source))
        for g in (int(round(m.fps)), int(round(2 * m.fps))):
            for lo in gap_starts(m.num_frames, g):
                hi = lo + g
                fm = gap_frames(m.num_frames, [(lo, hi)])
                feats = body_frame_features(m, known=fm > 0.5)          # nothing read from the gap
                mask = frame_mask_image(fm, j)
                xm = model.normalizer(feats.features).T.astype(np.float32) * mask
                base = base_fill(model, xm[None], mask[None])[0]

                def error(yy):
                    return float(np.linalg.norm(gap_positions(model, yy, feats, fm)[lo:hi] - gp[lo:hi], axis=-1).mean())
                e0 = error(base)
                s = np.arange(1, g + 1) / (g + 1)
                ratios = []
                for lim in limits:
                    y = base.copy()
                    y[pos_rows] = np.asarray(hermite_fill(xm, mask, limit=lim), np.float32)[pos_rows]
                    ratios.append(error(y) / e0)
                for b in pulls:
                    for w in windows:
                        mean = 0.5 * (xm[pos_rows, max(lo - w, 0):lo].mean(1) + xm[pos_rows, hi:hi + w].mean(1))
                        y = base.copy()
                        y[pos_rows, lo:hi] += b * np.sin(np.pi * s)[None] * (mean[:, None] - base[pos_rows, lo:hi])
                        ratios.append(error(y) / e0)
                recs.append((set_name, f"{group}/{g}", ratios))

print(f"{len(recs)} gaps; error over the shipped Hermite base's (mean per set and group)")
print("| set | group | gaps | " + " | ".join(names) + " |")
print("|---|---|---|" + "---|" * len(names))
for set_name in ("validation", "fit"):
    by = collections.defaultdict(list)
    for sn, grp, r in recs:
        if sn == set_name:
            by[grp].append(r)
    for grp, v in sorted(by.items()):
        v = np.array(v)
        print(f"| {set_name} | {grp} | {len(v)} | " + " | ".join(f"{x:.3f}" for x in v.mean(0)) + " |")
print("\n| variant | validation mean / p90 / max | fit mean / p90 / max | worst (set, group) mean |")
print("|---|---|---|---|")
for i, name in enumerate(names):
    cells = []
    for set_name in ("validation", "fit"):
        r = np.array([x[2][i] for x in recs if x[0] == set_name])
        cells.append(f"{r.mean():.4f} / {np.percentile(r, 90):.3f} / {r.max():.3f}")
    groups = collections.defaultdict(list)
    for sn, grp, r in recs:
        groups[(sn, grp)].append(r[i])
    worst = max((np.mean(v), k) for k, v in groups.items())
    print(f"| {name} | {cells[0]} | {cells[1]} | {worst[1][0]} {worst[1][1]} {worst[0]:.3f} |")
