"""Inference with a trained convolutional inpainting AE: restore a run, fill clips, infill a user's motion.

* :func:`load` rebuilds the model from a run folder (``run.json`` + checkpoint) as a :class:`TrainedCAE`;
* :func:`fill` runs it on ``x * mask`` for one clip image ``(D, T)`` or a batch ``(B, D, T)`` of *normalised*
  features, any T (raw outputs, as the paper; ``keep_known=True`` pastes the known entries back);
* :func:`process_motion` corrupts a whole motion (gaps, noise, joint dropout, missing joints), fills it,
  integrates the root trajectory back (:func:`~inbetween_jax.models.cae.features.to_global`) and fits BVH
  rotations (:func:`inbetween_jax.geometry.fit.fit_rotations`);
* :func:`infill` (options: the package's ``INFILL_OPTIONS``): ``inbetween infill --model cae --bvh IN.bvh --gaps 100:160,...``.
"""
from __future__ import annotations

import dataclasses
import functools
import os

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.data.features import Normalizer
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.geometry import forward_kinematics, quat_slerp
from inbetween_jax.errors import UserError
from inbetween_jax.geometry.fit import fit_rotations
from inbetween_jax.models.cae import global_base, model as cae_model
from inbetween_jax.models.cae.bank import (BANK_FILE, MARGIN, MatchBank, departure, gate_distance, match_enabled,
                                           match_gap, match_weight, speed_beside)
from inbetween_jax.models.cae.config import Config
from inbetween_jax.models.cae.edges import match_edge_velocity
from inbetween_jax.models.cae.features import (body_frame_features, body_positions, mirror_clips, mirror_rows,
                                               num_features, root_path_options, to_global)
from inbetween_jax.models.cae.masks import (add_position_noise, dropout_mask, frame_mask_image, gap_frames,
                                            gap_ranges, joints_mask)
from inbetween_jax.models.spec import InfillResult
from inbetween_jax.train.config import config_from_dict
from inbetween_jax.train.run import Run, RunError, restore_state

__all__ = ["TrainedCAE", "load", "fill", "slerp_gaps", "process_motion", "infill"]

class TrainedCAE:
    """A restored model: ``predict(x_norm (B, D, T), mask=None) -> (B, D, T)`` (jitted; ``x_norm`` already
    masked, ``mask`` 1 = known, used by the residual form), its normaliser, skeleton, config, ``num_joints``
    and checkpoint ``step``."""

    def __init__(self, params, cfg: Config, normalizer: Normalizer, skeleton: Skeleton, num_joints: int,
                 step: int, gate: tuple | None = None, match=None):
        self.params, self.cfg, self.normalizer, self.skeleton, self.step = params, cfg, normalizer, skeleton, step
        self.gate = gate            # (ContextBank, Gate) of ood.npz when model.ood_gate is on
        self.knn_cap = None         # (ContextBank, Gate): the gate's k-NN cap (model.knn_gate, gate.knn_cap)
        self.match = match          # bank.MatchBank of bank.npz when model.match_k > 0
        self.num_joints = int(num_joints)
        apply = functools.partial(cae_model.apply, cfg=cfg)
        if cfg.model.mirror_average:
            apply = functools.partial(_mirror_averaged, apply, mirror_rows(skeleton), normalizer)
        self._apply = jax.jit(apply)

    def predict(self, x_norm, mask=None):
        x = jnp.asarray(x_norm, jnp.float32)
        return self._apply(self.params, x, mask=jnp.ones_like(x) if mask is None else jnp.asarray(mask, jnp.float32))


def _mirror_averaged(apply, mirror, normalizer, params, x, mask):
    """``model.mirror_average``: the mean of ``apply``'s fill of ``x`` and the un-mirrored fill of the mirrored
    clip; mirror: :func:`~inbetween_jax.models.cae.features.mirror_rows`."""
    perm, sign = mirror
    m = mask[..., perm, :]
    flipped = apply(params, mirror_clips(x, perm, sign, normalizer) * m, mask=m)
    return 0.5 * (apply(params, x, mask=mask) + mirror_clips(flipped, perm, sign, normalizer))


def load(run: Run) -> TrainedCAE:
    """Restore ``run.step`` of a CAE run folder (:func:`inbetween_jax.train.run.load_run`).

    Raises:
        RunError: not a CAE run, or the checkpoint does not fit the run's config.
    """
    if run.model != "cae":
        raise RunError(f"{run.run_dir}: holds a {run.model} run, not a cae run")
    cfg = config_from_dict(Config, run.config)
    j = int(run.extra["num_joints"])
    init = functools.partial(cae_model.init_params, cfg=cfg, num_features=num_features(j))
    from inbetween_jax.train.optim import make_optimizer
    tx = make_optimizer(cfg.train)
    target = jax.eval_shape(lambda k: (lambda p: {"params": p, "opt_state": tx.init(p)})(init(k)),
                            jax.random.key(0))
    state = restore_state(run, target)
    normalizer = Normalizer(np.asarray(run.stats["mean"], np.float32), np.asarray(run.stats["std"], np.float32))
    from inbetween_jax.models.ood import run_gate
    gate = run_gate(run.run_dir, cfg.model.ood_gate)
    skeleton = Skeleton.from_dict(run.skeleton)
    match = None
    if match_enabled(cfg.model):
        from inbetween_jax.banks import bank_folder
        from inbetween_jax.models.scvae.bank import TransitionBank
        from inbetween_jax.train.run import load_run_file
        tb = load_run_file(bank_folder(run.run_dir, BANK_FILE), BANK_FILE, TransitionBank.load, "model.match_k")
        try:
            match = MatchBank.from_transition_bank(tb, skeleton, normalizer, j)
        except UserError as e:
            raise RunError(f"{run.run_dir}: {e}") from None
    from inbetween_jax.train.optim import inference_params
    params = inference_params(state["params"], state["opt_state"], cfg.train)     # the moving average, if kept
    model = TrainedCAE(params, cfg, normalizer, skeleton, j, run.step, gate, match)
    if gate is not None and cfg.model.knn_gate:
        from inbetween_jax.models.cae.gate import knn_cap
        model.knn_cap = knn_cap(run.run_dir)
    return model


def fill(model, x_norm, mask, keep_known: bool = False, chunk: int = 64, gate: bool = True) -> np.ndarray:
    """Model reconstruction of ``x_norm * mask``: (B, D, T) or (D, T) -> same shape.

    ``model`` is a :class:`TrainedCAE` (or any object with ``predict(x, mask)``).  A run with
    ``model.paste_known`` returns the known entries unchanged whatever ``keep_known`` says.  With
    ``model.net_edge_fade`` the network's fill meets each keyframe at the capture's speed
    (:func:`~inbetween_jax.models.cae.edges.match_edge_velocity`).  With ``model.ood_gate`` (and ``gate``) every
    gap -- a run of frames with nothing known -- is moved toward the base by the out-of-distribution gate
    (:func:`inbetween_jax.models.cae.gate.gate_clips`).
    """
    x = np.asarray(x_norm, np.float32)
    single = x.ndim == 2
    m = np.broadcast_to(np.asarray(mask, np.float32), x.shape)
    xb, mb = ((x * m)[None], m[None]) if single else (x * m, m)
    out = np.concatenate([np.asarray(model.predict(xb[i:i + chunk], mb[i:i + chunk]))
                          for i in range(0, len(xb), chunk)])
    cfg = getattr(model, "cfg", None)
    fade = float(getattr(cfg.model, "net_edge_fade", 0.0)) if cfg is not None else 0.0
    if fade > 0:                    # the network's fill meets each keyframe at the capture's speed (edges.py)
        out = match_edge_velocity(out, xb, mb, fade, slice(0, 3 * model.num_joints))
    if gate and getattr(model, "gate", None) is not None and model.cfg.model.ood_gate:
        from inbetween_jax.models.cae.gate import gate_clips
        out = gate_clips(model, xb, mb, out)[0]
    out = out[0] if single else out
    if keep_known:
        out = np.where(np.asarray(mask) > 0.5, x, out)
    return out


def slerp_gaps(local_quats, frame_mask) -> np.ndarray:
    """(T, J, 4) rotations with every gap replaced by a slerp between the frames around it (held at ends)."""
    q = np.array(local_quats, np.float64, copy=True)
    t_len = len(q)
    for a, b in gap_ranges(frame_mask):
        q0 = q[a - 1] if a > 0 else q[min(b, t_len - 1)]
        q1 = q[b] if b < t_len else q0
        w = (np.arange(a, b) - (a - 1)) / (b - a + 1)
        q[a:b] = quat_slerp(np.broadcast_to(q0, (b - a,) + q0.shape), np.broadcast_to(q1, (b - a,) + q1.shape),
                            w[:, None])
    return q


def process_motion(model, motion, gaps=(), noise: float = 0.0, dropout: float = 0.0, joints=(), seed: int = 0,
                   keep_known: bool = False) -> dict:
    """Corrupt a whole :class:`~inbetween_jax.data.Motion` (any length), fill it with ``model`` and convert back.

    gaps: ``[(start, stop), ...]`` frames to remove; noise: sigma (normalised units) on the position rows;
    dropout: per-frame joint dropout probability; joints: joint names or indices missing over the whole clip.
    Returns ``{"positions": (T, J, 3) global positions, "motion": Motion with fitted rotations,
    "frames": (T,) bool frames refitted, "error_cm": (mean, std) vs the input over the corrupted frames,
    "fk_gap_cm": mean distance between the BVH's FK and the predicted positions on those frames}``.
    """
    from inbetween_jax.metrics import mpjpe

    skel, j = model.skeleton, model.num_joints
    if not motion.skeleton.same_topology(skel):
        raise ValueError(f"{motion.source}: skeleton differs from the checkpoint's ({skel.num_joints} joints)")
    t_len = motion.num_frames
    fm = gap_frames(t_len, gaps)
    feats = body_frame_features(motion, known=(fm > 0.5) if gaps else None)   # nothing read from a gap's frames
    x = model.normalizer(feats.features).T.astype(np.float32)            # (D, T)
    rng = np.random.default_rng(seed)
    mask = frame_mask_image(fm, j)
    if joints:
        idx = [skel.index(n) if isinstance(n, str) else int(n) for n in joints]
        mask = mask * joints_mask(t_len, j, idx)
    if dropout > 0:
        mask = mask * dropout_mask(rng, (t_len,), j, dropout)
    x_in = add_position_noise(rng, x, j, noise) if noise > 0 else x
    gating = getattr(model, "gate", None) is not None and model.cfg.model.ood_gate
    y = fill(model, x_in, mask, keep_known=keep_known, gate=False)
    gated = []
    if gating:                      # once, here, so the per-gap scores come with the gated fill
        from inbetween_jax.models.cae.gate import gate_clips
        y, info = gate_clips(model, (x_in * mask)[None], mask[None], y[None])
        y, gated = y[0], info[0]
    if gaps and getattr(model, "match", None) is not None and match_enabled(model.cfg.model):
        gated = _matched(model, y, x_in * mask, feats, fm, gated)
    roots = root_path_options(model.cfg.model) if gaps and hasattr(model, "cfg") else {}
    pos = to_global(y, model.normalizer, j, feats.ref0, feats.yaw0, known_feats=feats.features, frame_mask=fm,
                    known_track=(feats.ref, feats.yaw), **roots)
    if gaps and gated and global_base.enabled(model.cfg.model):      # the base part of each gap, global
        pos = global_base.apply(model, pos, x_in * mask, mask, feats, fm, gated)
    scored = (fm < 0.5) if gaps else np.ones(t_len, bool)     # gaps: their frames; otherwise every frame
    err = mpjpe(body_positions(y, model.normalizer, j), body_positions(x, model.normalizer, j),
                mask=scored, root_relative=False)
    refit = scored
    ref_q = slerp_gaps(motion.local_quats, fm)
    lq, lp = fit_rotations(pos, ref_q, motion.local_pos, skel.parents, refit)
    out = dataclasses.replace(motion, local_quats=lq, local_pos=lp)
    fk = forward_kinematics(np.asarray(lq, np.float64), np.asarray(lp, np.float64), skel.parents)[1]
    fk_gap = float(np.linalg.norm(fk - pos, axis=-1)[refit].mean()) if refit.any() else 0.0
    return {"positions": pos.astype(np.float32), "motion": out, "frames": refit,
            "error_cm": (float(err[0]), float(err[1])), "fk_gap_cm": fk_gap, "gaps_ood": gated}



def _matched(model, y, x_masked, feats, frame_mask, gated) -> list:
    """Blend each whole gap of ``y`` (D, T), in place, toward its matched training window (:mod:`.bank`), by the
    match gate's weight.  Returns the per-gap records (``gated``'s, or new ones) with ``match_distance`` (the
    distance the gate reads, :func:`~.bank.gate_distance`), ``speed_beside`` (cm per frame) and ``match_weight``
    added."""
    from inbetween_jax.models.cae.masks import gap_ranges
    mc = model.cfg.model
    ref, yaw = feats.ref, feats.yaw                                   # read at known frames only
    rows = [dict(r) for r in gated] or [{"gap": [int(a), int(b)]} for a, b in gap_ranges(frame_mask)]
    for row in rows:
        a, b = row["gap"]
        fill_, dist = match_gap(model.match, x_masked, ref, yaw, a, b, mc.match_k, mc.match_disp)
        dep = None if fill_ is None else departure(y[:, a:b], fill_, feats.global_pos, a, b, model.normalizer,
                                                    model.num_joints)
        speed = speed_beside(ref, a, b)
        gd = gate_distance(dist, speed, mc.match_speed_scale)
        w = match_weight(gd, mc.match_lo, mc.match_hi) if dep is not None and dep <= mc.match_departure else 0.0
        if w > 0:
            y[:, a:b] += w * (fill_ - y[:, a:b])
        row.update(match_distance=gd if np.isfinite(gd) else None, match_departure=dep, match_weight=w,
                   speed_beside=round(speed, 4))
    return rows


def _save_npy(path, arr) -> None:
    with open(path, "wb") as f:                  # np.save(path) would append .npy to a temporary name
        np.save(f, arr)


def infill(args, run: Run) -> InfillResult:
    """Fill ``args.gaps`` of ``args.bvh`` with the run's model (``args.seed``; ``args.samples`` is not used:
    the CAE is deterministic).  One sample ``<stem>_filled`` (rotations refitted on the gap frames, swing
    only) plus ``<stem>_filled.npy``: (T, J, 3) predicted global joint positions of the checkpoint's joints.
    A file at another frame rate is resampled to the checkpoint's (gaps count the file's frames) and a rig
    with more joints is matched by name (:mod:`inbetween_jax.data.retarget`); the output is at the
    checkpoint's rate on the file's full skeleton.

    Raises:
        UserError: unreadable BVH, a skeleton lacking checkpoint joints, malformed or out-of-range gaps,
            non-finite output.
    """
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.data.user_input import finite_or_fail, parse_gaps, read_motion, resampled_gaps
    parse_gaps(args.gaps)                                             # syntax first
    user = read_motion(args.bvh)
    prep = prepare(user, args.bvh, Skeleton.from_dict(run.skeleton), run.fps)
    notes = []
    gaps = parse_gaps(args.gaps, user.num_frames, args.bvh, notes=notes)
    file_gaps = gaps                                                  # the file's own frame numbers (infill.json)
    motion = prep.motion
    if prep.ratio != 1.0:
        gaps = resampled_gaps(gaps, prep.ratio, motion.num_frames, args.gaps, args.bvh)
    if prep.note:
        notes.append(prep.note)
    model = load(run)
    res = process_motion(model, motion, gaps, seed=args.seed)
    finite_or_fail(run.run_dir, res["positions"], res["motion"].local_quats, res["motion"].local_pos)
    stem = os.path.splitext(os.path.basename(args.bvh))[0]
    pos = res["positions"] / prep.factor                              # back in the file's unit
    gen = np.zeros(motion.num_frames, bool)
    for a, b in gaps:
        gen[a:b] = True
    out = prep.on_user_rig(res["motion"], known=~gen)
    summary = {"input": args.bvh, "gaps": file_gaps, "frames": motion.num_frames, "step": model.step,
               "error_cm_mean": res["error_cm"][0], "fk_gap_cm": res["fk_gap_cm"],
               "refit_frames": int(np.sum(res["frames"]))}
    if res["gaps_ood"]:             # the gate and the match, per gap (in the order of "gaps")
        from inbetween_jax.models.ood import gate_note
        keys = ("ood_score", "knn_score", "knn_weight", "gate_weight", "match_distance", "speed_beside",
                "match_departure", "match_weight", "global_share", "global_weight")
        summary["gaps_ood"] = [dict({"gap_index": i}, **{k: g[k] for k in keys if k in g})
                               for i, g in enumerate(res["gaps_ood"])]
        for i, g in enumerate(res["gaps_ood"]):
            if g.get("match_weight", 0.0) >= 0.5:
                notes.append(f"gap {i + 1}: follows the nearest training motion (match distance "
                             f"{g['match_distance']:.4f}, departure {g['match_departure']:.2f}, weight "
                             f"{g['match_weight']:.2f})")
            elif g.get("knn_weight", 1.0) < 0.5:
                notes.append(f"gap {i + 1}: falls mostly back to the Hermite fill: the motion beside it lies "
                             f"farther from the training motion than the validation gaps' (k-NN score "
                             f"{g['knn_score']:.2f}, weight {g['gate_weight']:.2f})")
            elif g.get("gate_weight", 1.0) < 0.5:
                notes.append(f"gap {i + 1}: " + gate_note(g["ood_score"], g["gate_weight"], "the Hermite fill"))
            if "match_weight" in g and g.get("match_distance") is None:
                notes.append(f"gap {i + 1}: not matched to training motion: that needs {MARGIN} known frames at "
                             f"{run.fps:.0f} fps on each side")
    return InfillResult(samples=[(f"{stem}_filled", [out], gen)], summary=summary,
                        extra_files={f"{stem}_filled.npy": functools.partial(_save_npy, arr=pos)},
                        what="known frames", notes=notes)
