"""Tries at the CAE's motion matching inside a file, judged on the validation subjects plus the fit subjects'
gaps (each matched without its own subject's files), as ``experiments/cae_motion_match.py --fit-subjects`` does.

1. **The file's own motion as a bank** ("self-match"): each gap matched against the same file's known frames
   outside it (the gap and nothing else left out), for cyclic motion the training bank does not hold (jumps in
   place, runs); with ``--self-tempos`` those frames are also played faster and slower, so a cycle whose period
   does not fit the gap can match in phase.  Printed per activity group: the error with the self-match whole over
   the fill's.
2. **The spread of the k matched windows as the gate's score**: where the ``k`` nearest training windows disagree,
   a match may be a guess.  ``spread``: the mean joint distance (body frame, cm) of the k offset-blended windows
   from their mean; ``rel``: that over the body's travel beside the gap.  Each score gets its thresholds from
   :func:`~inbetween_jax.models.ood.calibrate_gate` by the project's rule, and each subject is also scored with
   thresholds chosen without it.
3. **Both banks**: the shipped gate on the training bank as it is, and where it stays shut the file's own match,
   blended in by a second gate on the self-match's distance (relative to the speed beside the gap, as the shipped
   gate's), its thresholds chosen by the same rule.

    python experiments/cae_match_probes.py inbetween_jax/assets/weights/cae      # about 10 min
"""
import argparse
import collections
import os

import numpy as np

from inbetween_jax.banks import scvae_bank
from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.models.cae.bank import (MARGIN, MatchBank, departure, gate_distance, match_candidates,
                                           match_weight, speed_beside)
from inbetween_jax.models.cae.features import body_frame_features, body_positions
from inbetween_jax.models.cae.in_file import gap_positions, gap_starts
from inbetween_jax.models.cae.infer import fill, load
from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
from inbetween_jax.models.ood import BLEND_WEIGHTS, calibrate_gate, gated_ratio, held_out_ratios
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--k", type=int, default=8)
p.add_argument("--disp", type=float, default=0.05)
p.add_argument("--departure", type=float, default=0.5)
p.add_argument("--self-tempos", default="1.0",
               help="comma-separated tempos the file's own frames are also played at when self-matched (1.25 is "
                    "faster): a cyclic motion whose period does not fit the gap can then match in phase")
a = p.parse_args()
run = load_run(a.run_dir)
model = load(run)
j, mc = model.num_joints, model.cfg.model
bank = MatchBank.from_transition_bank(scvae_bank(run, "cmu", "fit-subjects"), model.skeleton, model.normalizer, j)
self_tempos = tuple(float(t) for t in a.self_tempos.split(","))


def subject(name) -> str:
    return os.path.basename(str(name)).split("_")[0]


clip_subject = np.array([subject(n) for n in bank.names])
motions = [(m, None, "validation") for m in load_motions("cmu", "val-subjects")]
motions += [(m, clip_subject == subject(m.source), "fit") for m in load_motions("cmu", "fit-subjects")]
recs = []
for m, exclude, set_name in motions:
    gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
    group = activity_group(str(m.source))
    for g in (int(round(m.fps)), int(round(2 * m.fps))):                  # 1 and 2 s gaps, as the shipped choice
        for lo in gap_starts(m.num_frames, g):
            hi = lo + g
            fm = gap_frames(m.num_frames, [(lo, hi)])
            feats = body_frame_features(m, known=fm > 0.5)                # nothing read from the gap
            x = model.normalizer(feats.features).T.astype(np.float32)
            xm = x * frame_mask_image(fm, j)
            y = fill(model, x, frame_mask_image(fm, j))                    # the shipped fill, gated

            def error(yy):
                return np.linalg.norm(gap_positions(model, yy, feats, fm)[lo:hi] - gp[lo:hi], axis=-1).mean()
            base = error(y)

            def ratios(matched):                                           # at each blend weight, over the fill
                return [error(np.concatenate([y[:, :lo], y[:, lo:hi] + w * (matched - y[:, lo:hi]), y[:, hi:]], 1))
                        / base for w in BLEND_WEIGHTS]
            fills, dist = match_candidates(bank, xm, feats.ref, feats.yaw, lo, hi, a.k, a.disp, exclude)
            if fills is None:
                continue
            matched = fills.mean(0)
            body = np.stack([body_positions(f, model.normalizer, j) for f in fills])     # (k, g, J, 3)
            kp = np.asarray(feats.global_pos, np.float64)
            travel = 0.5 * (np.linalg.norm(kp[lo - 1] - kp[lo - MARGIN], axis=-1).mean()
                            + np.linalg.norm(kp[hi + MARGIN - 1] - kp[hi], axis=-1).mean())
            dep = departure(y[:, lo:hi], matched, feats.global_pos, lo, hi, model.normalizer, j)
            rec = {"set": set_name, "subject": subject(m.source), "group": f"{group}/{g}",
                   "distance": float(dist[0]), "beside": speed_beside(feats.ref, lo, hi),
                   "spread": float(np.linalg.norm(body - body.mean(0), axis=-1).mean()), "travel": float(travel),
                   "ratios_at": ratios(matched) if dep <= a.departure else [1.0] * len(BLEND_WEIGHTS)}
            rec["bank"] = rec["ratios_at"][-1] if dep <= a.departure else ratios(matched)[-1]      # whole
            segments = [(s, e) for s, e in ((0, lo), (hi, m.num_frames)) if e - s >= 2 * MARGIN + 2]
            own = MatchBank.from_features([(feats.features[s:e], feats.ref[s:e], feats.yaw[s:e], "own")
                                           for s, e in segments], model.normalizer, self_tempos)
            if own.clips:                                                  # the file's own known frames
                own_fills, own_d = match_candidates(own, xm, feats.ref, feats.yaw, lo, hi, 1, a.disp)
                if own_fills is not None:
                    own_dep = departure(y[:, lo:hi], own_fills[0], feats.global_pos, lo, hi, model.normalizer, j)
                    own_at = ratios(own_fills[0])
                    rec["self"] = (own_at[-1], own_dep <= a.departure)
                    rec["self_at"] = own_at if own_dep <= a.departure else [1.0] * len(BLEND_WEIGHTS)
                    rec["self_d"] = gate_distance(float(own_d[0]), rec["beside"], mc.match_speed_scale)
            recs.append(rec)

print(f"1. self-match: error with the file's own nearest window whole / the fill's ({len(recs)} gaps); the training "
      "bank's match whole beside it")
print("| set | group | gaps matched | mean | median | departure within the limit | mean of those "
      "| bank's match: mean |")
print("|---|---|---|---|---|---|---|---|")
for set_name in ("validation", "fit"):
    by = collections.defaultdict(list)
    for r in recs:
        if r["set"] == set_name and "self" in r:
            by[r["group"]].append(r["self"] + (r["bank"],))
    for grp, v in sorted(by.items()):
        rr, ok = np.array([x[0] for x in v]), np.array([x[1] for x in v])
        print(f"| {set_name} | {grp} | {len(v)} | {rr.mean():.3f} | {np.median(rr):.3f} | {ok.mean():.2f} | "
              f"{rr[ok].mean() if ok.any() else float('nan'):.3f} | {np.mean([x[2] for x in v]):.3f} |")

ratios_at, groups = [r["ratios_at"] for r in recs], [r["group"] for r in recs]
val, subjects = np.array([r["set"] == "validation" for r in recs]), np.array([r["subject"] for r in recs])
shipped = np.array([gate_distance(r["distance"], r["beside"], mc.match_speed_scale) for r in recs])
rel = np.array([r["spread"] / max(r["travel"], 1.0) for r in recs])
spread = np.array([r["spread"] for r in recs])
scores = {"the shipped gate distance d": shipped, "spread / travel": rel, "spread (cm)": spread}
scores.update({f"d (1 + rel / {c})": shipped * (1 + rel / c) for c in (0.05, 0.2, 1.0)})
scores.update({f"d (1 + spread / {c} cm)": shipped * (1 + spread / c) for c in (1.0, 2.0, 5.0)})
print(f"\n2. the gate's score ({len(recs)} gaps: validation {val.sum()}, fit {(~val).sum()}); x the fill")
print("| score | limits met | all: mean / max | validation mean | fit mean | each subject left out: mean / max "
      "| validation mean, left out |")
print("|---|---|---|---|---|---|---|")
for name, sc in scores.items():
    gate, summary = calibrate_gate(sc, ratios_at, groups=groups)
    r = gated_ratio(ratios_at, gate.weight(sc))
    held = held_out_ratios(sc, ratios_at, groups, subjects)
    print(f"| {name} | {summary['meets_limits']} | {r.mean():.4f} / {r.max():.3f} | {r[val].mean():.4f} | "
          f"{r[~val].mean():.4f} | {held.mean():.4f} / {held.max():.3f} | {held[val].mean():.4f} |")

# 3. the file's own match where the shipped bank gate stays shut, with its own gate on its own distance
bank_w = np.array([match_weight(d, mc.match_lo, mc.match_hi) for d in shipped])
bank_r = gated_ratio(ratios_at, bank_w)
shut = bank_w <= 0.0
combined = [r.get("self_at", [1.0] * len(BLEND_WEIGHTS)) if sh else [rb] * len(BLEND_WEIGHTS)
            for r, sh, rb in zip(recs, shut, bank_r)]
self_d = np.array([r.get("self_d", np.inf) for r in recs])
self_d = np.where(np.isfinite(self_d), self_d, np.nanmax(np.where(np.isfinite(self_d), self_d, np.nan)) * 10)
gate, summary = calibrate_gate(self_d, combined, groups=groups)
r = gated_ratio(combined, gate.weight(self_d))
held = held_out_ratios(self_d, combined, groups, subjects)
print(f"\n3. the file's own match where the shipped bank gate is shut ({shut.sum()} of {len(recs)} gaps); gate on "
      f"the self-match distance: lo {gate.lo:.5f} hi {gate.hi:.5f}, limits met {summary['meets_limits']}")
print("| fill | all: mean / max | validation mean | fit mean | each subject left out: mean / max | worst group |")
print("|---|---|---|---|---|---|")
for name, rr, hh in (("shipped: bank only", bank_r, None), ("bank, then the file's own match", r, held)):
    worst = max((rr[np.array([g_ == x for g_ in groups])].mean(), x) for x in set(groups))
    loso = "-" if hh is None else f"{hh.mean():.4f} / {hh.max():.3f}"
    print(f"| {name} | {rr.mean():.4f} / {rr.max():.3f} | {rr[val].mean():.4f} | {rr[~val].mean():.4f} | {loso} | "
          f"{worst[1]} {worst[0]:.3f} |")
