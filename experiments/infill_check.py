"""Score the shipped (or given) S-CVAE and CAE through `inbetween infill`'s own path on raw BVH files (any rig and
rate: each file is matched to the run's joints by name and resampled, as infill does), against the plain
baselines computed independently here: Slerp / lerp of the keyframes (S-CVAE) and straight-line interpolation of
the global joint positions across the gap (CAE).  The S-CVAE gets the frames beside its keyframes, as infill
passes them (used with ``model.context_base``, on in the shipped weights); with more than one sample, also the
best sample's error and the mean pairwise distance between samples over Slerp's error.  Gaps every ``--stride``
frames; per-gap ratios summarised (median, 90th percentile, maximum, share > 1.10x) overall and per activity
group, and the CAE's foot lift-offs per gap against the capture's and the straight line's (does a walking fill
step? ``metrics/steps.py``) and the share of its gaps that follow a matched training window (``model.match_k``).

    python experiments/infill_check.py FILE.bvh ... [--scvae-frames 20,30] [--cae-seconds 1,2] [--samples 10]
                                       [--scale 0.01]

``--scale F`` multiplies each file's lengths by F as it is read (0.01: the same capture in metres), to check that
``infill`` converts a file's unit (:func:`inbetween_jax.data.retarget.prepare`).
"""
import argparse
import dataclasses
import os

import numpy as np

from inbetween_jax.data import read_bvh
from inbetween_jax.data.activities import activity_group
from inbetween_jax.data.datasets import GENERIC_CONTACT_VELFACTOR
from inbetween_jax.data.retarget import prepare
from inbetween_jax.evaluation.worst_case import summarise
from inbetween_jax.metrics.steps import lift_offs
from inbetween_jax.models.cae.infer import load as load_cae, process_motion
from inbetween_jax.models.ood import Gate
from inbetween_jax.models.scvae import infer as scvae
from inbetween_jax.models.scvae.calibrate import _Zero
from inbetween_jax.models.scvae.context import clip_keyframes
from inbetween_jax.models.scvae.features import keyframe_contacts
from inbetween_jax.models.scvae.gate import slerp_base
from inbetween_jax.shipped import shipped_run
from inbetween_jax.train.config import apply_overrides

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("files", nargs="+")
p.add_argument("--scvae-frames", default="20,30")
p.add_argument("--cae-seconds", default="1,2")
p.add_argument("--stride", type=int, default=45)
p.add_argument("--samples", type=int, default=10, help="S-CVAE samples per gap (their errors averaged)")
p.add_argument("--scale", type=float, default=1.0, help="multiply each file's lengths by this as read")
p.add_argument("--scvae-set", action="append", default=[], metavar="model.KEY=VALUE",
               help="an inference switch of the S-CVAE for this check, e.g. model.bank_sample_weight=0.25")
a = p.parse_args()
srun, crun = shipped_run("scvae"), shipped_run("cae")
sm, cm = scvae.load(srun), load_cae(crun)
sm = dataclasses.replace(sm, cfg=apply_overrides(sm.cfg, a.scvae_set))
path_model = dataclasses.replace(sm, gate=(_Zero(), Gate(-1.0, 0.0)), cfg=dataclasses.replace(        # its base
    sm.cfg, model=dataclasses.replace(sm.cfg.model, context_base=True, ood_gate=True, context_gate=False)))
fa = tuple(sm.extra.get("forward_axis") or sm.skeleton.forward_axis())
vf = sm.extra.get("contact_velfactor", GENERIC_CONTACT_VELFACTOR)        # the keyframes' foot contacts, as infill
res = {"scvae": [], "cae": []}
for path in a.files:
    raw = read_bvh(path)
    raw = raw if a.scale == 1.0 else raw.scaled(a.scale)
    m = prepare(raw, path, sm.skeleton, srun.fps).motion
    gp = m.positions_of(m.local_quats, m.root_pos)
    group = activity_group(path)
    for n in [int(x) for x in a.scvae_frames.split(",")]:
        for k0 in range(3, m.num_frames - n - 2, a.stride):   # frames 0-1: often capture start-up
            k1 = k0 + n + 1
            contacts = keyframe_contacts(m, k0, vf, "start"), keyframe_contacts(m, k1, vf, "end")
            s, e = clip_keyframes(m, k0, k1, contacts)
            out = scvae.infill_between(sm, m.skeleton, s, e, n, a.samples, 0, fa)
            bq, br = slerp_base(m.local_quats[k0][None], m.root_pos[k0][None], m.local_quats[k1][None],
                                m.root_pos[k1][None], n)
            pos = m.positions_of(out["q"][:, 1:-1], out["r"][:, 1:-1])                           # (S, n, J, 3)
            each = np.linalg.norm(pos - gp[k0 + 1:k1], axis=-1).mean((1, 2))
            base = np.linalg.norm(m.positions_of(bq[0], br[0]) - gp[k0 + 1:k1], axis=-1).mean()
            hp = scvae.infill_between(path_model, m.skeleton, s, e, n, 1, 0, fa)
            path = np.linalg.norm(m.positions_of(hp["q"][0, 1:-1], hp["r"][0, 1:-1]) - gp[k0 + 1:k1], axis=-1).mean()
            i, j = np.triu_indices(len(pos), 1)
            apart = np.linalg.norm(pos[i] - pos[j], axis=-1).mean() if len(i) else 0.0
            res["scvae"].append((group, n, each.mean() / base, [each.min() / base, apart / base],
                                 each[0] / max(path, 1e-9)))
    cm_m = prepare(raw, path, cm.skeleton, crun.fps).motion
    for sec in [float(x) for x in a.cae_seconds.split(",")]:
        g = int(round(sec * crun.fps))
        for lo in range(10, cm_m.num_frames - g - 10, a.stride):
            out = process_motion(cm, cm_m, [(lo, lo + g)])
            pos = out["positions"]
            matched = float(any(r.get("match_weight", 0.0) > 0.5 for r in out["gaps_ood"]))
            w = (np.arange(1, g + 1) / (g + 1))[:, None, None]
            lin = gp[lo - 1] + w * (gp[lo + g] - gp[lo - 1])
            err = np.linalg.norm(pos[lo:lo + g] - gp[lo:lo + g], axis=-1).mean()
            feet, span = cm_m.skeleton.foot_joints(), slice(lo - 1, lo + g + 1)
            steps = [float(lift_offs(x, (feet[0], feet[2]))) for x in (pos[span], gp[span], np.concatenate(
                [gp[lo - 1:lo], lin, gp[lo + g:lo + g + 1]]))] + [matched]
            res["cae"].append((group, g, err / np.linalg.norm(lin - gp[lo:lo + g], axis=-1).mean(), steps))
for model, rows in res.items():
    print(f"{model} ({len(rows)} gaps of {os.path.basename(a.files[0])} ...):")
    for grp in ["all"] + sorted({r[0] for r in rows}):
        s = summarise([r[2] for r in rows if grp == "all" or r[0] == grp])
        if s["windows"]:
            print(f"  {grp:12s} n={s['windows']:3d} mean {s['mean']:.3f} median {s['median']:.3f} p90 {s['p90']:.3f} "
                  f"max {s['max']:.3f} share>1.10 {100 * s['share_worse_10pct']:.0f} %")
        if model == "scvae" and s["windows"]:
            sp = summarise([r[4] for r in rows if grp == "all" or r[0] == grp])
            print(f"  {'':12s} over its base inside a clip (the Hermite path; sample 0): mean {sp['mean']:.3f} "
                  f"median {sp['median']:.3f} p90 {sp['p90']:.3f} max {sp['max']:.3f} "
                  f"share>1.10 {100 * sp['share_worse_10pct']:.0f} %")
        if model == "scvae" and s["windows"] and a.samples > 1:
            st = np.mean([r[3] for r in rows if grp == "all" or r[0] == grp], 0)
            print(f"  {'':12s} best of {a.samples} / Slerp's error {st[0]:.3f}, samples apart (mean pairwise "
                  f"per-joint distance) / Slerp's error {st[1]:.3f}")
        if model == "cae" and s["windows"]:
            st = np.mean([r[3] for r in rows if grp == "all" or r[0] == grp], 0)
            print(f"  {'':12s} lift-offs per gap: fill {st[0]:.2f}, capture {st[1]:.2f}, straight line {st[2]:.2f}; "
                  f"gaps following a matched training window (model.match_k) {100 * st[3]:.0f} %")
