"""``inbetween infill --model scvae`` on BVH files: read the two keyframes (and the frames beside them) from the
user's files, match them to the checkpoint's rig, rate and unit (:mod:`inbetween_jax.data.retarget`), sample with
:func:`~inbetween_jax.models.scvae.infer.infill_between`, and return the samples on the user's rig with the notes
and per-sample scores ``infill.json`` reports.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from inbetween_jax.models.scvae.bank import sample_weight, sampled_mode
from inbetween_jax.models.scvae.features import keyframe_contacts
from inbetween_jax.models.scvae.infer import frame_range, infill_between, load, sampled_mode_gate
from inbetween_jax.models.scvae.timing import PARTS

__all__ = ["infill_files"]


def _is_lafan1_skeleton(skel) -> bool:
    return skel.names[0] == "Hips" and "LeftToe" in skel.names


def infill_files(args, run):
    """:func:`inbetween_jax.models.scvae.infer.infill` (the model contract's entry point, which calls this)."""
    from inbetween_jax.data import lafan1
    from inbetween_jax.data.datasets import GENERIC_CONTACT_VELFACTOR
    from inbetween_jax.data.retarget import expand, prepare, to_frame
    from inbetween_jax.data.user_input import check_skeleton, finite_or_fail, read_keyframe, same_skeleton
    from inbetween_jax.errors import UserError
    from inbetween_jax.models.spec import InfillResult, sample_names
    trained = load(run)
    cache = {}
    sp, sm, sf = read_keyframe(args.start, "--start", 0, cache)
    ep, em, ef = read_keyframe(args.end, "--end", -1, cache)
    if trained.skeleton is None:
        check_skeleton(sm.skeleton, sp, None, trained.extra["num_joints"])
    ps = prepare(sm, sp, trained.skeleton, run.fps)
    same_skeleton(em.skeleton, ep, sm.skeleton, sp)
    pe = ps if ep == sp else prepare(em, ep, trained.skeleton, run.fps)
    notes = list(dict.fromkeys(p.note for p in (ps, pe) if p.note))
    keyframes = {"start": f"{sp}:{sf}", "end": f"{ep}:{ef}"}                     # the files' own frame numbers
    sm, em, sf, ef = ps.motion, pe.motion, to_frame(ps, sf, "start"), to_frame(pe, ef, "end")
    skel = sm.skeleton
    lo, hi = frame_range(trained.cfg)
    if not lo <= args.frames <= hi:
        raise UserError(f"--frames {args.frames}: this S-CVAE checkpoint generates {lo}..{hi} frames between "
                        f"keyframes (trained with data.trans_max={hi})")
    lafan = bool(trained.extra.get("lafan1")) or _is_lafan1_skeleton(skel)
    ref = trained.skeleton or skel
    if lafan:
        fa, vf = lafan1.ROOT_FORWARD_AXIS, lafan1.CONTACT_VELFACTOR
    else:
        fa = tuple(trained.extra["forward_axis"]) if "forward_axis" in trained.extra else tuple(ref.forward_axis())
        vf = trained.extra.get("contact_velfactor", GENERIC_CONTACT_VELFACTOR)
    start = {"q": sm.local_quats[sf], "r": sm.root_pos[sf], "c": keyframe_contacts(sm, sf, vf, "start")}
    end = {"q": em.local_quats[ef], "r": em.root_pos[ef], "c": keyframe_contacts(em, ef, vf, "end")}
    m = trained.cfg.model
    past = m.uses_past_frame and sf >= 1
    if past or (m.context_base and sf >= 2):        # the frames before the start keyframe: its motion continued
        start.update(qp=sm.local_quats[sf - 1], rp=sm.root_pos[sf - 1])
        if sf >= 2:
            start.update(qp2=sm.local_quats[sf - 2], rp2=sm.root_pos[sf - 2])
    if m.context_base and ef + 2 < em.num_frames:                    # the two frames after the end keyframe
        end.update(qn=em.local_quats[ef + 1], rn=em.root_pos[ef + 1], qn2=em.local_quats[ef + 2],
                   rn2=em.root_pos[ef + 2])
    if past:
        notes.append(f"continuing the motion of the frame before the start keyframe ({sp})")
    elif m.uses_past_frame:
        notes.append(f"the start keyframe is the first frame of {sp}: no motion to continue (plain interpolation base)")
    res = infill_between(trained, skel, start, end, args.frames, args.samples, args.seed, fa)
    finite_or_fail(run.run_dir, res["q"], res["r"])
    context = res.get("context", "none")
    if context != "none":
        notes.append(f"following the motion beside the keyframes ({context}): Hermite path, not Slerp")
    gated = {k: res[k] for k in ("ood_score", "gate_weight", "sample_gate_weight") if k in res}
    sampling = trained.bank is not None and sampled_mode(m, args.samples)
    toward = float(sample_weight(m, sampled_mode_gate(gated))) if sampling else 0.0   # samples 1.. toward capture
    if gated:
        from inbetween_jax.models.ood import gate_note
        notes.append(gate_note(gated["ood_score"], gated["gate_weight"],
                               "Slerp / lerp" if context == "none" else "the Hermite path"))
        if sampling and m.bank_sample_gated and sampled_mode_gate(gated) < 0.5:
            notes.append(f"the {args.samples} samples stay close to the fill: the keyframes lie outside the captured "
                         f"motion the samples draw on (sampled-mode weight {toward:.2f})")
    t = args.frames + 2
    w = (np.arange(t) / (t - 1))[:, None, None]
    base_pos = (1 - w) * sm.local_pos[sf] + w * em.local_pos[ef]       # joints with position channels: lerp
    keys = None
    if ps.match is not None:        # the user's full rig: keyframes at both ends, the rest filled by expand
        idx = np.full(t, sf)          # frame ef is the end file's: taken from pe.full below, never from ps.full
        keys = dataclasses.replace(ps.full, local_quats=ps.full.local_quats[idx], local_pos=ps.full.local_pos[idx])
        keys.local_quats[-1], keys.local_pos[-1] = pe.full.local_quats[ef], pe.full.local_pos[ef]
    samples = []
    for name, q, r in zip(sample_names(args.samples), res["q"], res["r"]):
        pos = base_pos.copy()
        pos[:, 0] = r
        out = ps.to_file_unit(dataclasses.replace(sm, local_quats=q, local_pos=pos))
        samples.append((name, [out if keys is None else expand(out, keys, ps.match)], None))
    from inbetween_jax.evaluation.samples import sample_spread
    spread = sample_spread([m[0] for _, m, _ in samples])
    blends = [0.0] + [round(toward, 4)] * (args.samples - 1)     # sample 0 is the fill
    return InfillResult(samples=samples, summary={**keyframes, "frames": args.frames,
                                                  "samples": args.samples, "step": trained.step,
                                                  "past_frame": past, "context": context, **gated,
                                                  **spread,
                                                  "samples_ood": [dict(gated, sample=n, toward_captured=b,
                                                                       timing_shift=round(float(a), 4),
                                                                       timing_by_part={p: round(float(x), 4) for p, x
                                                                                       in zip(PARTS, by_part)})
                                                                  for n, b, a, by_part in zip(
                                                                      sample_names(args.samples), blends,
                                                                      res["timing_shift"], res["timing_by_part"])]
                                                  if gated else []},
                        notes=notes)
