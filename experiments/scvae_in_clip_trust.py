"""Could the S-CVAE's in-clip gate trust the network more on walks without losing on activities it never saw?

Inside a clip the gate has strict thresholds of its own (``context_gate_lo`` / ``_hi``).  The looser two-keyframe
thresholds gain on the validation walks at 30 and 50 frames and lose on unseen activities: the travel score cannot
tell a walk from a travelling dance step (docs/results/scvae.md, "past frames").  Two scores that might, each
letting gaps of at least ``--min-frames`` frames take the larger of the two gates' weights:

1. **Steady travel.**  ``|v0 + v1 - 2 d| / (|v0| + |v1| + 2 |d|)`` below ``tau``: ``v0`` / ``v1`` the root's
   floor velocity over the two frames before the start / after the end, ``d`` its mean over the gap (0: one
   constant velocity through the gap; toward 1: the body turns or stops beside it).
2. **A departure cap**, as the interaction model's (``models/interaction/gate.py``): the looser weight held to
   ``c * predicted / D``, ``D`` the network's departure from the Hermite path (cm, its fill at weight 1 against
   weight 0) and ``predicted`` the path's own error, from a log-linear fit on the training split's gaps (no
   network in it: log gap, log joint speed at the keyframes, log pose change, log root travel).

    python experiments/scvae_in_clip_trust.py [RUN_DIR] [--split val-activities] [--min-frames 20]
    python experiments/scvae_in_clip_trust.py inbetween_jax/assets/weights/scvae --split ''   # shipped weights

RUN_DIR (default ``runs/scvae_wo_activities``, trained on ``train.split=fit-activities``) must hold its
calibration (``inbetween calibrate-gate``); its validation gaps' ratios come from there.  The ``--split`` gaps
(activities the run never saw; '' for none) are filled here.  About 4 min for the default run, 1.5 for the shipped
weights.  Prints mean / p90 / max of each gap's error over the Hermite path and each activity group's mean.
"""
import argparse
import dataclasses
import json
import os
import time

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.data.datasets import val_split_of
from inbetween_jax.models.interaction.gate import departure_weight, fit_base_error
from inbetween_jax.models.ood import Gate, gated_ratio
from inbetween_jax.models.ood_runs import CALIBRATION_FILE
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.calibrate import _Zero, in_clip_records
from inbetween_jax.models.scvae.context import clip_keyframes
from inbetween_jax.train.run import load_run

TAUS = (0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 1.01)      # steadiness thresholds; 0: the shipped gate, 1.01: every gap
CAPS = (None, 1.0, 0.7, 0.5, 0.3)                  # departure caps; None: the looser gate uncapped


def gap_features(trained, motions, fa, departure=True, lengths=(10, 30, 50), stride=45, first=3) -> dict:
    """{(file:k0, frames): features} of in-clip gaps on :func:`in_clip_records`' grid with two frames on each
    side: ``steady``, ``path_err`` (the Hermite path's joint error, cm), ``v`` / ``pose`` / ``travel`` (the fit's
    inputs) and, with ``departure``, ``D`` (the network's departure from the path, cm)."""
    cfg = dataclasses.replace(trained.cfg, model=dataclasses.replace(
        trained.cfg.model, context_base=True, ood_gate=True, context_gate=False))
    at = {w: dataclasses.replace(trained, cfg=cfg, gate=(_Zero(), Gate(w - 1.0, w)))
          for w in ((0.0, 1.0) if departure else (0.0,))}
    out = {}
    for m in motions:
        gp, p = m.global_positions(), m.root_pos[:, [0, 2]]
        for n in lengths:
            for k0 in range(max(first, 2), m.num_frames - n - 3, stride):
                k1 = k0 + n + 1
                s, e = clip_keyframes(m, k0, k1)
                fill = {}                        # joint positions of the fill at each learned-fill weight
                for w, t in at.items():
                    o = infer.infill_between(t, m.skeleton, s, e, n, 1, 0, fa)
                    fill[w] = m.positions_of(o["q"][0, 1:-1], o["r"][0, 1:-1])
                dv, v0, v1 = (p[k1] - p[k0]) / (n + 1), (p[k0] - p[k0 - 2]) / 2, (p[k1 + 2] - p[k1]) / 2
                norm = np.linalg.norm
                body = gp[[k0, k1]] - gp[[k0, k1], :1]
                f = {"steady": norm(v0 + v1 - 2 * dv) / max(norm(v0) + norm(v1) + 2 * norm(dv), 1e-9),
                     "path_err": norm(fill[0.0] - gp[k0 + 1:k1], axis=-1).mean(),
                     "v": norm(gp[k0] - gp[k0 - 1], axis=-1).mean() + norm(gp[k1 + 1] - gp[k1], axis=-1).mean(),
                     "pose": norm(body[1] - body[0], axis=-1).mean(), "travel": norm(p[k1] - p[k0])}
                if departure:
                    f["D"] = norm(fill[1.0] - fill[0.0], axis=-1).mean()
                out[(f"{os.path.basename(str(m.source))}:{k0}", n)] = {k: float(v) for k, v in f.items()}
    return out


def design(recs) -> np.ndarray:
    """(N, 5) the fit's inputs: 1, log frames, log joint speed, log pose change, log root travel."""
    col = lambda k: np.log(np.array([r[k] for r in recs]) + 1e-3)      # noqa: E731
    return np.stack([np.ones(len(recs)), col("frames"), col("v"), col("pose"), col("travel")], 1)


def scored(recs, summary, loose, cap=None, coef=None) -> np.ndarray:
    """Each gap's error over the path with the looser weight where ``loose`` (B,) holds, capped by ``cap``."""
    inside, outside = Gate(summary["context_lo"], summary["context_hi"]), Gate(summary["lo"], summary["hi"])
    s = np.array([r["score"] for r in recs])
    w = np.where(loose, np.maximum(inside.weight(s), outside.weight(s)), inside.weight(s))
    if cap is not None:
        pred = np.exp(design(recs) @ coef)
        w = np.where(loose, np.minimum(w, departure_weight(cap, pred, [r["D"] for r in recs])), w)
    return gated_ratio([r["ratios_at"] for r in recs], w)


def line(recs, x) -> str:
    groups = {}
    for r, v in zip(recs, x):
        groups.setdefault(f"{activity_group(r['name'])}/{r['frames']}", []).append(v)
    per = ", ".join(f"{g} {np.mean(v):.3f}" for g, v in sorted(groups.items()) if not g.endswith("/10"))
    return f"{x.mean():.4f} / {np.quantile(x, 0.9):.3f} / {x.max():.3f} | {per}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_dir", nargs="?", default="runs/scvae_wo_activities")
    p.add_argument("--split", default="val-activities")
    p.add_argument("--min-frames", type=int, default=20)
    a = p.parse_args()
    t0 = time.time()
    with open(os.path.join(a.run_dir, CALIBRATION_FILE)) as f:
        cal = json.load(f)
    run = load_run(a.run_dir)
    trained = infer.load(run)
    fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
    split = run.config["train"].get("split", "fit")
    join = lambda recs, feats: [dict(r, **feats[(r["name"], r["frames"])]) for r in recs   # noqa: E731
                                if (r["name"], r["frames"]) in feats]
    val = load_motions("cmu", val_split_of(split))
    sets = [("validation subjects", join(cal["context_records"], gap_features(trained, val, fa)))]
    if a.split:
        held = load_motions("cmu", a.split)
        sets.append((a.split, join(in_clip_records(trained, held, fa), gap_features(trained, held, fa))))
    fit = list(gap_features(trained, load_motions("cmu", split), fa, departure=False, stride=90).items())
    fit = [dict(f, frames=k[1]) for k, f in fit]
    coef = fit_base_error(design(fit), [f["path_err"] for f in fit])
    res = np.log([f["path_err"] for f in fit]) - design(fit) @ coef
    s = cal["summary"]
    print(f"gates: inside a clip {s['context_lo']:.4f} / {s['context_hi']:.4f}; two keyframes {s['lo']:.4f} / "
          f"{s['hi']:.4f}; the looser one only from {a.min_frames} frames on.  Path-error fit on {len(fit)} {split} "
          f"gaps: R^2 {1 - res.var() / np.log([f['path_err'] for f in fit]).var():.3f}, residual sd {res.std():.3f}")
    print("| variant | gaps | mean / p90 / max | groups at 30 and 50 frames |")
    print("|---|---|---|---|")
    for name, recs in sets:
        long = np.array([r["frames"] >= a.min_frames for r in recs])
        steady = np.array([r["steady"] for r in recs])
        for tau in TAUS:
            print(f"| steady < {tau} | {name} ({len(recs)}) | {line(recs, scored(recs, s, long & (steady < tau)))} |")
        for cap in CAPS[1:]:
            print(f"| cap {cap} | {name} ({len(recs)}) | {line(recs, scored(recs, s, long, cap, coef))} |")
    print(f"({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
