"""Choose the CAE's motion matching (``model.match_k``, ``match_disp``, and the gate ``match_lo`` / ``match_hi``) on
the validation subjects, through ``inbetween infill``'s own path (global joint error, root bounded as shipped).

Each gap's fill (the run's, gated: its Hermite fill where the gate closes) is blended toward its matched training
window (:mod:`inbetween_jax.models.cae.bank`) at the weights of :data:`~inbetween_jax.models.ood.BLEND_WEIGHTS`;
:func:`~inbetween_jax.models.ood.calibrate_gate` picks the distance thresholds by the project's rule (every
activity group and length at most 1.00x the fill, p90 <= 1.05x, max <= 1.5x, then the lowest mean).  The bank
holds the ``fit-subjects`` files only (``inbetween build-bank`` writes the same).

Each subject is also scored with the thresholds chosen on the other validation subjects ("leave one subject out").

    python experiments/cae_motion_match.py RUN_DIR [--k 4,8] [--disp 0.05,0.25] [--departure 0.5] [--tempos 1]
        [--mirror] [--split val-subjects] [--list] [--figure docs/figures/cae_match_calibration.png]
"""
import argparse
import os
import collections

import numpy as np

from inbetween_jax.banks import scvae_bank
from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.evaluation.worst_case import summarise
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.metrics.steps import lift_offs
from inbetween_jax.models.cae.bank import MatchBank, departure, gate_distance, match_gap, match_weight, speed_beside
from inbetween_jax.models.cae.features import body_frame_features
from inbetween_jax.models.cae.in_file import gap_positions, gap_starts
from inbetween_jax.models.cae.infer import fill, load
from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
from inbetween_jax.models.ood import BLEND_WEIGHTS, calibrate_gate, gated_ratio, held_out_ratios
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--k", default="4,8")
p.add_argument("--disp", default="0.05,0.25", help="weights of the root displacement and turn")
p.add_argument("--split", default="val-subjects")
p.add_argument("--seconds", default="1,2")
p.add_argument("--tempos", default="1", help="the bank's clips also played at these speeds")
p.add_argument("--mirror", action="store_true", help="the bank's clips' mirror images too")
p.add_argument("--list", action="store_true", help="list every gap of the first config")
p.add_argument("--figure", default=None, help="write the first config's calibration figure (PNG) here, against the "
                                                "distance the run's gate reads and its lo / hi")
p.add_argument("--leaky", action="store_true",
               help="features of the whole file, gap frames included (the evaluation before 2026-12-05)")
p.add_argument("--fit-subjects", action="store_true",
               help="also the fit subjects' gaps, each matched against the bank without its own subject's files "
                    "(everyday, dance, martial arts, ... which the validation subjects lack); the gate is chosen "
                    "on all")
p.add_argument("--speed-scales", default=None,
               help="also try gates on the distance over (1 + root speed beside the gap / c), for these c "
                    "(cm per frame): a match may lie farther where the body travels")
p.add_argument("--departure", type=float, default=0.5,
               help="matches departing further from the fill (bank.departure) are never used")
a = p.parse_args()
run = load_run(a.run_dir)
model = load(run)
j, feet = model.num_joints, model.skeleton.foot_joints()
bank = MatchBank.from_transition_bank(scvae_bank(run, "cmu", "fit-subjects"), model.skeleton, model.normalizer, j,
                                  tempos=[float(t) for t in a.tempos.split(",")], mirror=a.mirror)
configs = [(int(k), float(d)) for k in a.k.split(",") for d in a.disp.split(",")]
records = collections.defaultdict(list)


def subject(name) -> str:
    return os.path.basename(str(name)).split("_")[0]


motions = [(m, None) for m in load_motions("cmu", a.split)]
if a.fit_subjects:          # the bank's own subjects too, each matched against the bank without its own files
    clip_subject = np.array([subject(n) for n in bank.names])
    motions += [(m, clip_subject == subject(m.source)) for m in load_motions("cmu", "fit-subjects")]
for m, exclude in motions:
    gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
    group = activity_group(str(m.source))
    for sec in [float(s) for s in a.seconds.split(",")]:
        g = int(round(sec * m.fps))
        for lo in gap_starts(m.num_frames, g):
            fm = gap_frames(m.num_frames, [(lo, lo + g)])
            mask = frame_mask_image(fm, j)
            # as infill: no known frame's features read the gap (--leaky: the whole file's, as before 2026-12-05)
            feats = body_frame_features(m, known=None if a.leaky else fm > 0.5)
            x = model.normalizer(feats.features).T.astype(np.float32)
            ref, yaw = feats.ref, feats.yaw
            y = fill(model, x, mask)                                  # as shipped: gated
            w = (np.arange(1, g + 1) / (g + 1))[:, None, None]
            lin_err = np.linalg.norm(gp[lo - 1] + w * (gp[lo + g] - gp[lo - 1]) - gp[lo:lo + g], axis=-1).mean()
            span = slice(lo - 1, lo + g + 1)

            def positions(yy):
                return gap_positions(model, yy, feats, fm)
            base_pos = positions(y)
            base_err = np.linalg.norm(base_pos[lo:lo + g] - gp[lo:lo + g], axis=-1).mean()
            beside = speed_beside(ref, lo, lo + g)                   # known frames only, cm per frame
            for k, disp in configs:
                mf, dist = match_gap(bank, x * mask, ref, yaw, lo, lo + g, k, disp, exclude=exclude)
                if mf is None:
                    continue
                at, steps = [], []
                for bw in BLEND_WEIGHTS:
                    yy = y.copy()
                    yy[:, lo:lo + g] += bw * (mf - y[:, lo:lo + g])
                    pos = positions(yy)
                    at.append(np.linalg.norm(pos[lo:lo + g] - gp[lo:lo + g], axis=-1).mean() / base_err)
                    steps.append(float(lift_offs(pos[span], (feet[0], feet[2]))))
                dep = departure(y[:, lo:lo + g], mf, feats.global_pos, lo, lo + g, model.normalizer, j)
                used = dep <= a.departure
                records[(k, disp)].append({
                    "set": "validation" if exclude is None else "fit, own subject left out",
                    "subject": subject(m.source), "group": f"{group}/{g}", "at_one": at[-1], "score": dist,
                    "departure": dep, "beside": beside, "ratios_at": at if used else [1.0] * len(at),
                    "base_x_linear": base_err / lin_err,
                    "steps": (steps if used else [steps[0]] * len(steps),
                              float(lift_offs(base_pos[span], (feet[0], feet[2]))),
                              float(lift_offs(gp[span], (feet[0], feet[2]))))})
gates = {}
for (k, disp), rs in records.items():
    gate, summ = gates[(k, disp)] = calibrate_gate([r["score"] for r in rs], [r["ratios_at"] for r in rs],
                                groups=[r["group"] for r in rs])
    wts = gate.weight([r["score"] for r in rs])
    r = gated_ratio([r["ratios_at"] for r in rs], wts)
    s = summarise(list(r))
    lin = r * np.array([x["base_x_linear"] for x in rs])
    print(f"k {k} disp {disp}: gate lo {gate.lo:.6f} hi {gate.hi:.6f} (limits met: {summ['meets_limits']}); "
          f"{s['windows']} gaps x the fill: mean {s['mean']:.3f} median {s['median']:.3f} p90 {s['p90']:.3f} "
          f"max {s['max']:.3f}; x linear {lin.mean():.3f} (fill alone "
          f"{np.mean([x['base_x_linear'] for x in rs]):.3f}); open (w > 0.5) {np.mean(wts > 0.5):.2f}; "
          f"ungated mean {np.mean([x['ratios_at'][-1] for x in rs]):.3f}")
    # each subject scored with the thresholds chosen on the other four (how much the choice depends on them)
    subjects = np.array([x["subject"] for x in rs])
    held = held_out_ratios([x["score"] for x in rs], [x["ratios_at"] for x in rs], [x["group"] for x in rs], subjects)
    sh = summarise(list(held))
    print(f"  leave one subject out: mean {sh['mean']:.3f} p90 {sh['p90']:.3f} max {sh['max']:.3f} "
          f"(per subject {', '.join(f'{u} {held[subjects == u].mean():.3f}' for u in sorted(set(subjects)))})")
    for grp in sorted({x["group"] for x in rs}):
        sel = np.array([x["group"] == grp for x in rs])
        near = [int(np.argmin(np.abs(np.asarray(BLEND_WEIGHTS) - w_))) for w_ in wts]
        st = np.array([(x["steps"][0][i], *x["steps"][1:]) for x, i in zip(rs, near)])[sel]
        print(f"  {grp:12s} n {sel.sum():3d} x the fill mean {r[sel].mean():.3f} max {r[sel].max():.3f}; "
              f"open {np.mean(wts[sel] > 0.5):.2f}; lift-offs per gap gated {st[:, 0].mean():.2f} "
              f"fill {st[:, 1].mean():.2f} capture {st[:, 2].mean():.2f}")
    mc = model.cfg.model
    shipped = gated_ratio([x["ratios_at"] for x in rs],
                          [match_weight(gate_distance(x["score"], x["beside"], mc.match_speed_scale), mc.match_lo,
                                        mc.match_hi) for x in rs])
    for name in dict.fromkeys(x["set"] for x in rs):
        sel = np.array([x["set"] == name for x in rs])
        for label, rr in (("this gate", r), (f"the run's lo {mc.match_lo} hi {mc.match_hi}", shipped)):
            worst = max((rr[sel & np.array([x["group"] == g_ for x in rs])].mean(), g_)
                        for g_ in {x["group"] for x, o in zip(rs, sel) if o})
            sm = summarise(list(rr[sel]))
            print(f"  {name}, {label}: {sm['windows']} gaps mean {sm['mean']:.3f} p90 {sm['p90']:.3f} "
                  f"max {sm['max']:.3f}; worst group {worst[1]} {worst[0]:.3f}")

if a.speed_scales:                  # the distance relative to the body's speed beside the gap (known frames only)
    rs = records[configs[0]]
    ratios, groups = [x["ratios_at"] for x in rs], [x["group"] for x in rs]
    subjects, val = np.array([x["subject"] for x in rs]), np.array([x["set"] == "validation" for x in rs])
    for c in [float(v) for v in a.speed_scales.split(",")]:
        sc = np.array([gate_distance(x["score"], x["beside"], c) for x in rs])
        gate, summ = calibrate_gate(sc, ratios, groups=groups)
        r = gated_ratio(ratios, gate.weight(sc))
        held = held_out_ratios(sc, ratios, groups, subjects)
        print(f"distance / (1 + speed beside / {c}): lo {gate.lo:.5f} hi {gate.hi:.5f} (limits met: "
              f"{summ['meets_limits']}); all {r.mean():.4f} max {r.max():.3f}; validation {r[val].mean():.3f}; fit "
              f"{r[~val].mean():.4f}; leave one subject out: mean {held.mean():.4f} max {held.max():.3f}")

if a.list:
    print("the first config's gaps, nearest first: ratio to the fill with the match whole, departure, distance")
    for x in sorted(records[configs[0]], key=lambda x: x["score"]):
        print(f"{x['at_one']:7.2f} departure {x['departure']:6.2f} distance {x['score']:.4f} {x['subject']} "
              f"{x['group']}")

if a.figure:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from inbetween_jax.viz_frames import save_atomic
    rs = records[configs[0]]
    sc_ = float(model.cfg.model.match_speed_scale)           # the run's gate: its distance, lo and hi
    for x in rs:
        x["gate_distance"] = gate_distance(x["score"], x["beside"], sc_)
    dist_label = (f"match distance / (1 + speed beside / {sc_:g} cm per frame)" if sc_ > 0 else "match distance")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, key, label, limit in ((axes[0], "gate_distance", f"{dist_label} (the run's lo / hi)", None),
                                  (axes[1], "departure", "departure from the fill / body travel beside the gap",
                                   a.departure)):
        for used, colour, name in ((True, "tab:blue", "departure <= limit"), (False, "tab:red", "departure > limit")):
            for held, marker, size in (("validation", "o", 12), ("fit, own subject left out", ".", 4)):
                pts = [x for x in rs if (x["departure"] <= a.departure) == used and x["set"] == held]
                if pts:
                    ax.scatter([x[key] for x in pts], [x["at_one"] for x in pts], s=size, c=colour, marker=marker,
                               alpha=1.0 if held == "validation" else 0.35, label=f"{name} ({held})")
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        for x_ in ([limit] if limit is not None else [model.cfg.model.match_lo, model.cfg.model.match_hi]):
            ax.axvline(x_, color="tab:red", ls="--", lw=0.8)
    axes[0].set_ylabel("error with the match whole / the fill's")
    axes[0].legend(fontsize=8)
    sets = " + ".join(dict.fromkeys(x["set"] for x in rs))
    fig.suptitle(f"CAE motion matching: {sets} ({len(rs)} gaps, k {configs[0][0]}, disp {configs[0][1]})",
                 fontsize=9)
    fig.tight_layout()
    save_atomic(a.figure, lambda f: fig.savefig(f, format="png", dpi=110))
    print("wrote", a.figure)
