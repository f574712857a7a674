"""The CAE's gaps inside files with the Hermite root path's edge tangents pulled toward the secant: the shipped (or
given) run's fill, its root moved onto ``L + lam (H - L)`` (H the limited cubic Hermite root path the fill is held
to, ``model.root_bound``; L the straight line), per gap error over straight lines between the global joint positions
beside the gap, per activity group and length.  A probe of whether the root path's tangents overshoot on dance.

    python experiments/cae_root_tangent_probe.py [--run RUN_DIR] (--split val-subjects | --files F.bvh ...)
                                                 [--lams 1,0.75,0.5,0.25,0]
"""
import argparse

import numpy as np

from inbetween_jax.baselines import linear_fill
from inbetween_jax.data import load_motions, read_bvh
from inbetween_jax.data.activities import activity_group
from inbetween_jax.data.retarget import prepare
from inbetween_jax.evaluation.worst_case import summarise
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.models.cae.features import body_frame_features, root_base_path
from inbetween_jax.models.cae.in_file import SECONDS, gap_starts
from inbetween_jax.models.cae.infer import load, process_motion
from inbetween_jax.models.cae.masks import gap_frames
from inbetween_jax.shipped import shipped_run
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--run", default=None, help="a CAE run folder (default: the shipped weights)")
p.add_argument("--split", default=None)
p.add_argument("--files", nargs="+", default=None)
p.add_argument("--lams", default="1,0.75,0.5,0.25,0")
a = p.parse_args()
run = load_run(a.run) if a.run else shipped_run("cae")
model = load(run)
lams = [float(x) for x in a.lams.split(",")]
motions = ([prepare(read_bvh(f), f, model.skeleton, run.fps).motion for f in a.files] if a.files
           else load_motions("cmu", a.split or "val-subjects"))
rows = []                                     # (group, frames, [error over straight lines per lam])
for m in motions:
    gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
    for sec in SECONDS:
        g = int(round(sec * float(m.fps)))
        for lo in gap_starts(m.num_frames, g):
            hi = lo + g
            fm = gap_frames(m.num_frames, [(lo, hi)])
            pos = process_motion(model, m, [(lo, hi)])["positions"]
            ref = np.asarray(body_frame_features(m, known=fm > 0.5).ref, np.float64)
            hermite = root_base_path(ref, fm)
            line = np.asarray(linear_fill(ref.T, (fm > 0.5)[None]), np.float64).T
            w = (np.arange(1, g + 1) / (g + 1))[:, None, None]
            straight = np.linalg.norm(gp[lo - 1] + w * (gp[hi] - gp[lo - 1]) - gp[lo:hi], axis=-1).mean()
            errs = []
            for lam in lams:
                shift = (line + lam * (hermite - line) - hermite)[lo:hi]
                q = pos[lo:hi].copy()
                q[..., 0] += shift[:, None, 0]
                q[..., 2] += shift[:, None, 1]
                errs.append(float(np.linalg.norm(q - gp[lo:hi], axis=-1).mean() / straight))
            rows.append((activity_group(str(m.source)), g, errs))
print("| group | frames | gaps | " + " | ".join(f"lam {x:g}: mean / p90 / max" for x in lams) + " |")
print("|---|---|---|" + "---|" * len(lams))
for grp in ["all"] + sorted({r[0] for r in rows}):
    for g in sorted({r[1] for r in rows}):
        sel = [r[2] for r in rows if r[1] == g and grp in ("all", r[0])]
        if sel:
            cells = [summarise([e[i] for e in sel]) for i in range(len(lams))]
            print(f"| {grp} | {g} | {len(sel)} | " + " | ".join(
                f"{c['mean']:.3f} / {c['p90']:.3f} / {c['max']:.3f}" for c in cells) + " |")
