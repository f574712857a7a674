"""Inference with a trained interaction model: restore a run folder, roll out in-betweens for two characters
and infill users' BVH files (``inbetween infill --model interaction``).

    trained = load(load_run("runs/interaction"))
    feats = infill_features(trained, context, keyframes, frames=40, num_samples=3)   # (3, 2, 40, J, 9) world

Users' inputs go to each character's keyframe space exactly as
:func:`~inbetween_jax.models.interaction.features.keyframe_sample` does for training samples.
"""
from __future__ import annotations

import dataclasses
import os

import jax
import numpy as np

from inbetween_jax.data.retarget import to_frame
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.data.user_input import check_skeleton, finite_or_fail, read_keyframe, same_skeleton
from inbetween_jax.errors import UserError
from inbetween_jax.geometry import quat_fix_sign_np, quat_from_forward_up, quat_inv, quat_mul, quat_normalize
from inbetween_jax.geometry.fit import fit_rotations
from inbetween_jax.models.interaction.bank import (BANK_FILE, MotionBank, apply_bank, bank_enabled, ease_into_keypose,
                                                  foot_indices)
from inbetween_jax.models.interaction.config import Config
from inbetween_jax.models.interaction.features import (apply_space, key_space_inputs, root_space,
                                                       world_joint_features)
from inbetween_jax.models.interaction.model import sample_rollouts
from inbetween_jax.models.spec import InfillResult
from inbetween_jax.train.config import config_from_dict
from inbetween_jax.train.run import Run, RunError, load_run_file, restore_state

__all__ = ["Trained", "load", "load_bank", "infill_features", "features_to_motion", "infill"]

@dataclasses.dataclass
class Trained:
    """A restored interaction model: config, parameters ``{gen, ref, pae, disc}`` and what it was trained on."""
    cfg: Config
    params: dict
    num_joints: int
    forward_axis: np.ndarray          # (3,) the root's local facing axis
    skeleton: Skeleton | None
    step: int
    run_dir: str
    bank: MotionBank | None = None    # motion bank (``bank.npz`` in the run folder) when the config uses one
    gate: tuple | None = None         # (scorer, Gate) of ``ood.npz`` when ``model.ood_gate`` is on (:mod:`.gate`)
    base_error: np.ndarray | None = None  # (4,) ood.npz's interpolation-error fit when ``model.departure_cap`` is on

    def gate_kwargs(self) -> dict:
        """:func:`.gate.gate_rollouts`'s departure cap and sample arguments for this run."""
        m = self.cfg.model
        return {"cap": m.departure_cap, "coef": self.base_error, "samples": m.bank_sample_gated}


def load(run: Run, with_gate: bool = True) -> Trained:
    """Restore the parameters of ``run`` (its latest / chosen checkpoint), with its gate unless ``with_gate`` is
    false (calibration, which writes it).

    Raises:
        RunError: not an interaction run, incomplete ``run.json`` or an unreadable checkpoint (one line).
    """
    from inbetween_jax.models.interaction.train import init_state
    if run.model != "interaction":
        raise RunError(f"{run.run_dir}: holds a {run.model} run, not an interaction run")
    try:
        cfg = config_from_dict(Config, run.config)
        J = int(run.extra["num_joints"])
        fa = np.asarray(run.extra["forward_axis"], np.float64).reshape(3)
    except (KeyError, TypeError, ValueError) as e:
        raise RunError(f"{run.run_dir}: run.json is incomplete for an interaction run ({e})") from None
    target = jax.eval_shape(lambda k: init_state(cfg, J, k), jax.random.key(0))
    state = restore_state(run, target)
    skel = Skeleton.from_dict(run.skeleton) if run.skeleton else None
    from inbetween_jax.models.interaction.gate import BASE_ERROR_KEY
    from inbetween_jax.models.ood import load_gate_array, run_gate
    if cfg.model.departure_cap < 0:
        raise RunError(f"{run.run_dir}: model.departure_cap must not be negative (got {cfg.model.departure_cap})")
    gate = run_gate(run.run_dir, cfg.model.ood_gate) if with_gate else None
    capped = gate is not None and cfg.model.departure_cap > 0
    coef = load_gate_array(run.run_dir, BASE_ERROR_KEY, "model.departure_cap") if capped else None
    from inbetween_jax.train.optim import inference_params
    params = inference_params(state["params"], state["opt"], cfg.train)            # the moving average, if kept
    return Trained(cfg, params, J, fa, skel, int(run.step), run.run_dir,
                   load_bank(run.run_dir, cfg, J), gate, coef)


def load_bank(run_dir: str, cfg: Config, num_joints: int) -> MotionBank | None:
    """The run folder's motion bank when ``cfg`` turns it on (:func:`.bank.bank_enabled`), else None.

    Raises:
        RunError: a negative bank / texture setting, or the bank file missing or unreadable (one line).
    """
    m = cfg.model
    if min(m.bank_k, m.bank_weight, m.texture_sigma) < 0 or m.bank_weight > 1:
        raise RunError(f"{run_dir}: model.bank_k, model.bank_weight (at most 1) and model.texture_sigma must not "
                       f"be negative (got {m.bank_k}, {m.bank_weight}, {m.texture_sigma})")
    if not bank_enabled(m):
        return None
    path = os.path.join(run_dir, BANK_FILE)
    bank = load_run_file(run_dir, BANK_FILE, MotionBank.load, "model.bank_k / model.texture_sigma")
    if bank.takes[0].shape[2] != num_joints or abs(bank.pos_scale - cfg.data.pos_scale) > 1e-12:
        raise RunError(f"{path}: the bank has {bank.takes[0].shape[2]} joints at position scale {bank.pos_scale:g}, "
                       f"the model {num_joints} at {cfg.data.pos_scale:g}")
    return bank


def infill_features(trained: Trained, context, keyframes, frames: int, num_samples: int, seed: int = 0,
                    gate_info: dict | None = None):
    """Roll the interaction network out for ``frames`` frames after two characters' context windows.

    context: (2, n_input, J, 9) world features (positions + forward/up of global rotations) of the frames
    up to the start frame; keyframes: (2, J, 9) world features of the keyposes.  It is rolled out for
    exactly ceil(frames / n_pred) steps (no early stop) and the first ``frames`` frames are kept.  Models
    with a time-to-arrival input (``model.tta`` / ``model.residual``) are told that the keyframe follows
    frame ``frames``; the paper's model has none and only its output is cut.  A run whose config turns the
    motion bank on gets its in-between and texture over the frames (:func:`.bank.apply_bank`); with
    ``model.ood_gate`` the frames are then moved toward per-character interpolation by the out-of-distribution
    gate (:mod:`.gate`), and ``gate_info`` (a dict, when given) receives ``ood_score``, ``gate_weight`` and
    ``departure_weight`` (the part of the weight that ``model.departure_cap`` sets).
    Returns (S, 2, frames, J, 9) world features (float64).
    """
    cfg, fa = trained.cfg, trained.forward_axis
    b = key_space_inputs(context, keyframes, fa, cfg.data.pos_scale)
    R, t = root_space(keyframes[:, 0], fa)                                      # key spaces -> world (file units)
    steps = -(-frames // cfg.data.n_pred)
    fn = jax.jit(lambda p, w, kp, rr, rt, k: sample_rollouts(p, w, kp, rr, rt, k, cfg, fa.astype(np.float32),
                                                            steps, num_samples, threshold=-1.0, gap=frames)[0])
    out = fn(trained.params, b["x"], b["keypose"], b["rel_R"], b["rel_t"], jax.random.key(seed))
    if trained.bank is not None:
        feet = foot_indices(trained.skeleton)
        out = apply_bank(trained.bank, cfg.model, out, b["x"], b["keypose"], [frames], feet,
                         (b["rel_R"], b["rel_t"]))
    if trained.gate is not None and cfg.model.ood_gate:   # toward interpolation as the window leaves the training takes
        from inbetween_jax.models.interaction.gate import gate_rollouts
        parts = {}
        out, score, weight = gate_rollouts(trained.gate, out, b["x"], b["keypose"], [frames],
                                           parts=parts, **trained.gate_kwargs())
        if gate_info is not None:
            gate_info.update(ood_score=float(score[0]), gate_weight=float(weight[0]),
                             departure_weight=float(parts["departure_weight"][0]))
    if cfg.model.ease_frames:      # the last frames take up the jump onto the keypose (.bank.ease_into_keypose)
        out = ease_into_keypose(out, b["keypose"], [frames], cfg.model.ease_frames)
    out = np.asarray(out, np.float64)[:, 0, :, :frames]                        # (S, 2, frames, J, 9)
    out[..., :3] /= cfg.data.pos_scale
    return apply_space(out, R[None, :, None], t[None, :, None])


def features_to_motion(feats, motion, start: int, key_motion, key_frame: int):
    """A character's generated world features (T, J, 9) -> a Motion on ``motion``'s skeleton holding
    [frame ``start`` of ``motion``, the T generated frames, frame ``key_frame`` of ``key_motion``].

    Rotations: the predicted global rotations (forward / up) made local, then every bone swung onto the
    predicted position of its main child with :func:`inbetween_jax.geometry.fit.fit_rotations`
    (swing-only; twist from the predicted rotations; bone lengths are the skeleton's, so the written
    positions differ from the network's by its bone-length error).
    """
    skel = motion.skeleton
    gq = quat_normalize(quat_from_forward_up(np.asarray(feats[..., 3:], np.float64)))
    par = np.asarray(skel.parents[1:])
    lq = np.concatenate([gq[:, :1], quat_mul(quat_inv(gq[:, par]), gq[:, 1:])], axis=1)
    lp = np.broadcast_to(motion.local_pos[start], lq.shape[:-1] + (3,)).copy()
    lq, lp = fit_rotations(feats[..., :3], lq, lp, skel.parents, np.ones(len(lq), bool))
    q = np.concatenate([motion.local_quats[start][None], lq, key_motion.local_quats[key_frame][None]])
    p = np.concatenate([motion.local_pos[start][None], lp, key_motion.local_pos[key_frame][None]])
    return dataclasses.replace(motion, local_quats=quat_fix_sign_np(quat_normalize(q)), local_pos=p)


def _sample_names(n: int) -> list:
    width = max(2, len(str(n - 1)))
    return [f"sample_{i:0{width}d}" for i in range(n)]


def infill(args, run: Run) -> InfillResult:
    """``inbetween infill --model interaction``: args ``a``, ``b``, ``key_a``, ``key_b``, ``frames``,
    ``samples``, ``seed``.  Each sample is two Motions (``<name>_A.bvh`` / ``<name>_B.bvh``) of frames + 2
    frames: the start frame, the generated frames, the keyframe.

    Raises:
        UserError: unreadable / mismatching inputs, too little context, too many frames, non-finite output.
    """
    cfg = config_from_dict(Config, run.config)
    skel = Skeleton.from_dict(run.skeleton) if run.skeleton else None
    num_joints = run.extra.get("num_joints")
    n_in = cfg.data.n_input
    cache = {}
    chars, notes, own = [], [], []                    # own: the files' frame numbers (infill.json)
    for opt, kopt, spec, kspec in (("--a", "--key-a", args.a, args.key_a), ("--b", "--key-b", args.b, args.key_b)):
        path, m, start = read_keyframe(spec, opt, -1, cache)
        kpath, km, kf = read_keyframe(kspec, kopt, -1, cache)
        same_skeleton(km.skeleton, kpath, m.skeleton, path)
        if skel is None:
            check_skeleton(m.skeleton, path, skel, num_joints)
        prep = _on_run_rig(m, path, skel, run.fps, notes)
        kprep = prep if kpath == path else _on_run_rig(km, kpath, skel, run.fps, [])
        own.append((start, kf))
        start, kf = to_frame(prep, start, "start"), to_frame(kprep, kf, "end")
        if start < n_in - 1:
            raise UserError(f"{opt} {path}: the model needs {n_in} frames of context (at {run.fps or m.fps:g} fps) up "
                            f"to the start frame; choose a later start frame")
        chars.append((path, prep, start, kpath, kprep, kf))
    pa, pb = chars[0][0], chars[1][0]
    ma, mb = chars[0][1].motion, chars[1][1].motion
    if abs(ma.frame_time - mb.frame_time) > 1e-6:
        raise UserError(f"{pb}: {mb.fps:.3f} fps differs from {pa} ({ma.fps:.3f} fps)")
    if args.frames > cfg.model.max_frames:
        raise UserError(f"--frames {args.frames}: this interaction checkpoint rolls out at most "
                        f"{cfg.model.max_frames} frames (model.max_frames)")
    context = np.stack([world_joint_features(p.motion)[s - n_in + 1:s + 1] for _, p, s, _, _, _ in chars])
    keys = np.stack([world_joint_features(kp.motion.slice(kf, kf + 1))[0] for _, _, _, _, kp, kf in chars])
    trained = load(run)
    gated = {}
    feats = infill_features(trained, context, keys, args.frames, args.samples, args.seed, gated)
    finite_or_fail(run.run_dir, feats)
    samples = []
    for i, name in enumerate(_sample_names(args.samples)):
        motions = []
        for c, (path, prep, s, _, kprep, kf) in enumerate(chars):
            motion = features_to_motion(feats[i, c], prep.motion, s, kprep.motion, kf)
            finite_or_fail(run.run_dir, motion.local_quats, motion.local_pos)
            motions.append(_on_user_rig(motion, prep, s, kprep, kf))
        samples.append((name, motions, None))
    summary = {"a": f"{pa}:{own[0][0]}", "b": f"{pb}:{own[1][0]}", "key_a": f"{chars[0][3]}:{own[0][1]}",
               "key_b": f"{chars[1][3]}:{own[1][1]}", "frames": args.frames, "samples": args.samples,
               "step": trained.step, **gated}
    from inbetween_jax.evaluation.samples import sample_spread
    summary.update(sample_spread([tuple(m) for _, m, _ in samples]))       # both dancers' joints, per sample
    if gated:
        from inbetween_jax.models.ood import gate_note
        note = gate_note(gated["ood_score"], gated["gate_weight"], "per-character interpolation")
        if gated["departure_weight"] < 0.999:        # the cap, not the speed score, held the learned part back
            note += (f" (of which model.departure_cap keeps {gated['departure_weight']:.2f}: the fill left "
                     "interpolation by more than interpolation's own error is expected to be here)")
        ungated = len(samples) > 1 and not trained.cfg.model.bank_sample_gated
        if ungated and gated["gate_weight"] < 0.999:
            note += (f"; samples 1-{len(samples) - 1} are left as the motion bank made them "
                     "(model.bank_sample_gated=false)")
        notes.append(note)
        summary["samples_ood"] = [dict(gated, sample=n, **({"gate_weight": 1.0, "departure_weight": 1.0}
                                                           if ungated and i else {}))
                                  for i, (n, _, _) in enumerate(samples)]
    return InfillResult(samples=samples, summary=summary, what="start / keyframe", notes=list(dict.fromkeys(notes)))


def _on_run_rig(motion, path: str, skel, fps, notes: list):
    """A user's file on the run's joints, frame rate and unit: a Prepared (``factor``: run units per file unit).
    Larger rigs are matched by joint name and another unit (e.g. the 1/128-scaled CMU salsa files) is detected
    from the leg length and converted (:func:`inbetween_jax.data.retarget.prepare`)."""
    from inbetween_jax.data.retarget import prepare
    prep = prepare(motion, path, skel, fps)
    if prep.note:
        notes.append(prep.note)
    return prep


def _on_user_rig(motion, prep, start: int, kprep, key_frame: int):
    """A generated Motion on the run's rig and unit -> the user's file rig and unit (at the run's rate)."""
    keys = prep.end_keys(start, kprep, key_frame, motion.num_frames) if prep.on_other_rig else None
    return prep.on_user_rig(motion, keys)
