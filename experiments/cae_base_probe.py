"""Other non-learned fills for the CAE's gaps inside a file, against the limited cubic Hermite (the network's
pre-fill, and the CAE's base until 2026-12-07), judged on the validation subjects and on the fit subjects' files: no
network and no bank take part, so every file the training saw may score them.

Where the gate shuts (most gaps), the CAE's fill is its base.  Each variant here changes the base's body pose in
the gap (the body-frame joint positions; the root keeps the Hermite root path, as ``model.root_bound`` holds it):

* ``limit L``: the Hermite's tangent limiter at L times the secant slope (3 in the pre-fill; 0 is a smoothstep
  between the edges, with no edge velocity);
* ``pull B / W``: the pose pulled toward the mean of the known frames within W frames of each edge, by
  ``B sin(pi s)`` at gap phase s (0 at both edges, B mid-gap).  For motion that oscillates faster than the gap
  (jumps in place, dance steps), the mean pose is the smallest-error guess for a phase nobody knows;
* ``damp k`` (``/ limit L``): the cubic with the edge tangents' departures from the secant fading as
  ``exp(-k frames)`` from their edge (``hermite_fill(damping=k)``), unlimited (or limited at L): the fill leaves
  and reaches the gap with the motion's own velocity and settles onto the straight line over a long gap;
* ``edge fade k``: the limited Hermite plus the part of each edge tangent the limiter cut, fading as ``exp(-k
  frames)`` from its edge (``hermite_fill(edge_fade=k)``; the shipped base since 2026-12-07, ``model.base_edge_fade
  = 0.3``).  The limiter sets a tangent that opposes the secant to 0, so the limited fill leaves a joint still
  while the capture moves it: a speed step at the keyframe;
* ``... + root fade k``: the body as ``edge fade`` (``--root-body-fade``, 0.3 as shipped) and the root's floor path,
  which ``model.root_bound`` holds to the limited Hermite of the known root positions, on that Hermite edge-faded
  too (``model.root_edge_fade``, shipped 0.4 since 2026-12-07);
* ``rot ...`` (``--rotations``): the body pose from the joints' rotations instead of their positions.  Each local
  rotation (the root's included) becomes a rotation vector about the frame before the gap, ``log(q_{a-1}^-1
  q_t)``; those rows and the root's height are filled as named (``linear``: Slerp; ``limited``, ``edge fade k``,
  ``damp k`` as above), then forward kinematics gives the body-frame positions.  Bones keep their length and
  limbs swing on arcs, where the positional fills cut across chords.

Printed: per set and (activity group, gap length), the mean error over the shipped base's, and the pooled mean /
p90 / max, for every variant; and how much a joint's step changes across the keyframes (the speed step where the
fill meets the capture; the capture's own change beside it for reference).

    python experiments/cae_base_probe.py inbetween_jax/assets/weights/cae        # about 3 min
"""
import argparse
import collections
import copy
import dataclasses

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.geometry.quaternion import quat_align, quat_from_axis_angle, quat_mul, quat_conj, quat_to_axis_angle
from inbetween_jax.models.cae.features import body_frame_features
from inbetween_jax.models.cae.gate import base_fill
from inbetween_jax.models.cae.in_file import gap_positions, gap_starts, keyframe_step_change
from inbetween_jax.models.cae.infer import load
from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
from inbetween_jax.baselines import hermite_fill, linear_fill
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--limits", default="3,1.5,1,0.5,0")
p.add_argument("--pulls", default="0.25,0.5,0.75,1.0")
p.add_argument("--windows", default="8,15,30")
p.add_argument("--dampings", default="", help="e.g. 0.05,0.1,0.2,0.3 (empty: none)")
p.add_argument("--edge-fades", default="", help="limiter 3 with the cut tangent fading back near the edges")
p.add_argument("--root-fades", default="", help="the root path edge-faded as well (e.g. 0.3,0.4,0.5)")
p.add_argument("--root-body-fade", type=float, default=0.3, help="the body's edge fade with --root-fades")
p.add_argument("--damp-limits", default="none", help="limiters with each damping (none = unlimited)")
p.add_argument("--rotations", action="store_true", help="also the body from filled rotations (Slerp, Hermite forms)")
a = p.parse_args()
model = load(load_run(a.run_dir))
model.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, root_edge_fade=0.0))
j = model.num_joints


def floats(text):
    return [float(v) for v in text.split(",") if v]


limits, pulls, windows, dampings = floats(a.limits), floats(a.pulls), floats(a.windows), floats(a.dampings)
fades, root_fades = floats(a.edge_fades), floats(a.root_fades)


def with_root_fade(k):
    """The model with its root path's base edge-faded by ``k``."""
    out = copy.copy(model)
    out.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, root_edge_fade=k))
    return out


root_models = [with_root_fade(k) for k in root_fades]
damped = [(k, None if v == "none" else float(v)) for k in dampings for v in a.damp_limits.split(",")]
names = ([f"limit {v:g}" for v in limits] + [f"pull {b:g} / {w:g}" for b in pulls for w in windows]
         + [f"damp {k:g}" + ("" if lim is None else f" / limit {lim:g}") for k, lim in damped]
         + [f"edge fade {k:g}" for k in fades]
         + [f"edge fade {a.root_body_fade:g} + root fade {k:g}" for k in root_fades])
ROTATION_FILLS = {"rot linear (Slerp)": linear_fill, "rot limited": hermite_fill,
                  "rot edge fade 0.3": lambda x, k: hermite_fill(x, k, edge_fade=0.3),
                  "rot damp 0.1": lambda x, k: hermite_fill(x, k, limit=None, damping=0.1)} if a.rotations else {}
names += list(ROTATION_FILLS)
pos_rows = slice(0, 3 * j)                       # body-frame joint positions; the last three rows: root velocities



def rotation_filled(m, lo, hi, fm, fill):
    """Motion m with the gap [lo, hi)'s local rotations and root height filled as rotation vectors about frame
    lo - 1 (module docstring)."""
    q = np.asarray(m.local_quats, np.float64)
    ref = np.broadcast_to(q[lo - 1], q.shape)
    axis, angle = quat_to_axis_angle(quat_align(quat_mul(quat_conj(ref), q), np.array([1.0, 0, 0, 0])))
    rows = np.concatenate([(axis * angle[..., None]).reshape(len(q), -1).T, np.asarray(m.local_pos)[:, 0, 1:2].T])
    out = np.asarray(fill(rows, np.broadcast_to(fm[None], rows.shape)), np.float64)
    vec = out[:-1].T.reshape(q.shape[:2] + (3,))
    ang = np.linalg.norm(vec, axis=-1)
    qf, lp = q.copy(), np.array(m.local_pos, np.float64)
    qf[lo:hi] = quat_mul(ref, quat_from_axis_angle(vec / np.maximum(ang, 1e-12)[..., None], ang))[lo:hi]
    lp[lo:hi, 0, 1] = out[-1, lo:hi]
    return dataclasses.replace(m, local_quats=qf.astype(np.float32), local_pos=lp.astype(np.float32))


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
                base = base_fill(model, xm[None], mask[None], edge_fade=False)[0]     # the limited Hermite

                def error(yy, model_=model):
                    pos = gap_positions(model_, yy, feats, fm)
                    jumps.append(keyframe_step_change(pos, lo, hi))
                    return float(np.linalg.norm(pos[lo:hi] - gp[lo:hi], axis=-1).mean())
                jumps = []
                e0 = error(base)
                s = np.arange(1, g + 1) / (g + 1)
                ratios = []
                for lim in limits:
                    y = base.copy()
                    y[pos_rows] = np.asarray(hermite_fill(xm, mask, limit=lim), np.float32)[pos_rows]
                    ratios.append(error(y) / e0)
                for b in pulls:
                    for w in (int(v) for v in windows):
                        mean = 0.5 * (xm[pos_rows, max(lo - w, 0):lo].mean(1) + xm[pos_rows, hi:hi + w].mean(1))
                        y = base.copy()
                        y[pos_rows, lo:hi] += b * np.sin(np.pi * s)[None] * (mean[:, None] - base[pos_rows, lo:hi])
                        ratios.append(error(y) / e0)
                for k, lim in damped:
                    y = base.copy()
                    y[pos_rows] = np.asarray(hermite_fill(xm, mask, limit=lim, damping=k), np.float32)[pos_rows]
                    ratios.append(error(y) / e0)
                for k in fades:
                    y = base.copy()
                    y[pos_rows] = np.asarray(hermite_fill(xm, mask, edge_fade=k), np.float32)[pos_rows]
                    ratios.append(error(y) / e0)
                if root_models:
                    y = base.copy()
                    y[pos_rows] = np.asarray(hermite_fill(xm, mask, edge_fade=a.root_body_fade), np.float32)[pos_rows]
                    ratios += [error(y, m_) / e0 for m_ in root_models]
                for fill in ROTATION_FILLS.values():
                    y = base.copy()
                    alt = body_frame_features(rotation_filled(m, lo, hi, fm, fill), known=fm > 0.5)
                    y[pos_rows] = model.normalizer(alt.features).T.astype(np.float32)[pos_rows]
                    ratios.append(error(y) / e0)
                recs.append((set_name, f"{group}/{g}", ratios, jumps[1:], keyframe_step_change(gp, lo, hi)))

print(f"{len(recs)} gaps; error over the shipped Hermite base's (mean per set and group)")
print("| set | group | gaps | " + " | ".join(names) + " |")
print("|---|---|---|" + "---|" * len(names))
for set_name in ("validation", "fit"):
    by = collections.defaultdict(list)
    for sn, grp, r, *_ in recs:
        if sn == set_name:
            by[grp].append(r)
    for grp, v in sorted(by.items()):
        v = np.array(v)
        print(f"| {set_name} | {grp} | {len(v)} | " + " | ".join(f"{x:.3f}" for x in v.mean(0)) + " |")
print("\n| variant | validation mean / p90 / max | fit mean / p90 / max | worst (set, group) mean | "
      "step change at the keyframes, cm per frame (the capture's) |")
print("|---|---|---|---|---|")
for i, name in enumerate(names):
    cells = []
    for set_name in ("validation", "fit"):
        r = np.array([x[2][i] for x in recs if x[0] == set_name])
        cells.append(f"{r.mean():.4f} / {np.percentile(r, 90):.3f} / {r.max():.3f}")
    groups = collections.defaultdict(list)
    for sn, grp, r, *_ in recs:
        groups[(sn, grp)].append(r[i])
    worst = max((np.mean(v), k) for k, v in groups.items())
    jump = np.mean([x[3][i] for x in recs])
    print(f"| {name} | {cells[0]} | {cells[1]} | {worst[1][0]} {worst[1][1]} {worst[0]:.3f} | {jump:.3f} "
          f"({np.mean([x[4] for x in recs]):.3f}) |")
