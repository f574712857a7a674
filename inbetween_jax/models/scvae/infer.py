"""S-CVAE inference: load a trained run, sample transitions on benchmark windows, in-between users' keyframes.

All N samples of a chunk of windows come from one compiled call (``vmap`` over PRNG keys of the
``lax.scan`` rollout, see :func:`inbetween_jax.models.scvae.model.sample`).

Canonical space of users' keyframes.  They are put in the space of the training windows with
:func:`inbetween_jax.data.windows.canonicalize` (centred in XZ on the mean root of the two keyframes -- the
training windows use the mean over the window, which the network never sees: it is only fed velocities and
offsets between frames -- and turned so that the start keyframe faces +X), and the samples are mapped back
with the inverse rigid motion.
"""
from __future__ import annotations

import dataclasses
import functools
import os

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.models.scvae import model as M
from inbetween_jax.models.scvae.bank import (BANK_FILE, TransitionBank, bank_enabled, bank_needed, bank_sample_blend,
                                             bank_searched, blend, knn_base_path, knn_transition, pad_base_path,
                                             sample_timing_spread, sample_weight, sampled_mode)
from inbetween_jax.models.scvae.context import context_kind, context_offsets, known_sides, neighbours, onto_context
from inbetween_jax.models.scvae.features import keyframe_contacts, past_frame_inputs
from inbetween_jax.models.scvae.losses import fk_positions
from inbetween_jax.models.scvae.timing import PARTS, body_parts, part_amplitudes

__all__ = ["MIN_FRAMES", "Trained", "load", "load_bank", "infill", "frame_range", "infill_between",
           "sample_transitions", "bank_transitions", "bank_samples"]

MIN_FRAMES = 3          # L = frames + 1 >= 4 frames between keyframes (model.rollout)

@dataclasses.dataclass
class Trained:
    """A restored S-CVAE run: ``cfg`` (Config), ``state`` (the train state: params, disc, stats ...), ``step``,
    the training ``skeleton`` (or None) and ``extra`` (num_joints, lafan1, forward_axis, contact_velfactor)."""
    cfg: object
    state: dict
    step: int
    skeleton: object
    extra: dict
    bank: TransitionBank | None = None      # transition bank (``bank.npz`` in the run folder) when the config uses one
    gate: tuple | None = None               # (ContextBank, Gate) of ``ood.npz`` when ``model.ood_gate`` is on
    context_gate: object | None = None      # the Gate used inside a clip (``model.context_gate``, .gate.context_gate)

    @property
    def params(self) -> dict:
        return self.state["params"]

    @property
    def stats(self) -> dict:
        return self.state["stats"]


def load(run) -> Trained:
    """Restore the chosen (``run.step``) checkpoint of an S-CVAE run (:func:`inbetween_jax.train.run.load_run`).

    Raises:
        RunError: the folder does not hold an S-CVAE run, or its checkpoint does not fit its config.
    """
    from inbetween_jax.data import Skeleton
    from inbetween_jax.models.scvae.config import Config
    from inbetween_jax.models.scvae.features import stats_like
    from inbetween_jax.models.scvae.train import make_init_fn
    from inbetween_jax.train.config import ConfigError, config_from_dict
    from inbetween_jax.train.run import RunError, restore_state
    if run.model != "scvae":
        raise RunError(f"{run.run_dir}: holds a {run.model} run, not an S-CVAE run")
    try:
        cfg = config_from_dict(Config, run.config)
    except (ConfigError, TypeError) as e:
        raise RunError(f"{run.run_dir}: run.json holds no S-CVAE config ({e})") from None
    skeleton = Skeleton.from_dict(run.skeleton) if run.skeleton else None
    num_joints = run.extra.get("num_joints") or (skeleton.num_joints if skeleton is not None else None)
    if num_joints is None:
        raise RunError(f"{run.run_dir}: run.json records no skeleton (num_joints unknown)")
    init_fn = make_init_fn(cfg, stats_like(int(num_joints)), int(num_joints))
    state = restore_state(run, jax.eval_shape(init_fn, jax.random.key(0)))
    from inbetween_jax.train.optim import inference_params
    state = dict(state, params=inference_params(state["params"], state["opt_g"], cfg.train))   # the average, if kept
    from inbetween_jax.models.ood import run_gate
    gate = run_gate(run.run_dir, cfg.model.ood_gate)
    from inbetween_jax.models.scvae.gate import context_gate
    inside = context_gate(run.run_dir) if gate is not None and cfg.model.context_gate else None
    return Trained(cfg, state, int(run.step), skeleton, dict(run.extra, num_joints=int(num_joints)),
                   load_bank(run.run_dir, cfg.model, int(num_joints)), gate, inside)


def _sample_gate(gated: dict):
    """The gate weight the sampled mode scales its pull toward captured transitions by: the two-keyframe gate's, also
    inside a clip, where the fill itself follows the stricter in-clip thresholds (None without a gate)."""
    return gated.get("sample_gate_weight", gated.get("gate_weight"))


def load_bank(run_dir: str, model_cfg, num_joints: int) -> TransitionBank | None:
    """The run folder's transition bank when ``model_cfg`` uses one (:func:`.bank.bank_needed`), else None.

    Raises:
        RunError: a negative or out-of-range setting, or the bank file missing, unreadable or on another skeleton.
    """
    from inbetween_jax.train.run import RunError, load_run_file
    m = model_cfg
    if m.bank_k < 0 or not 0 <= m.bank_weight <= 1 or m.bank_tau < 0:
        raise RunError(f"{run_dir}: model.bank_k and model.bank_tau must not be negative and model.bank_weight must "
                       f"lie in 0..1 (got {m.bank_k}, {m.bank_tau}, {m.bank_weight})")
    if not bank_needed(m):
        return None
    if m.bank_base and m.bank_k < 1:
        raise RunError(f"{run_dir}: model.bank_base needs model.bank_k >= 1 (got {m.bank_k})")
    need = "model.bank_base" if m.bank_base else "model.bank_k" if m.bank_k > 0 else "model.bank_sample_weight"
    from inbetween_jax.banks import bank_folder
    folder = bank_folder(run_dir, BANK_FILE)          # its own, or the CAE's beside it when build-bank shared it
    bank = load_run_file(folder, BANK_FILE, TransitionBank.load, need)
    if bank.num_joints != num_joints:
        raise RunError(f"{os.path.join(folder, BANK_FILE)}: the bank has {bank.num_joints} joints, the model "
                       f"{num_joints}")
    return bank


def frame_range(cfg) -> tuple:
    """Transition lengths (generated frames between the keyframes) the S-CVAE was trained for."""
    return MIN_FRAMES, int(cfg.data.trans_max)


# ----------------------------------------------------------------------------- benchmark windows
@functools.partial(jax.jit, static_argnames=("cfg", "max_length", "parents"))
def _sample_chunk(params, stats, start, target, keys, cfg, max_length, parents):
    res = M.sample(params, cfg, stats, start, target, max_length, keys, max_length)
    out = res["out"]
    mid = max_length // 2
    extra = {}
    if cfg.bidirectional:  # raw forward / backward poses at the middle frame (MMPE)
        pf = fk_positions(res["fwd"]["q"][:, :, mid - 1], res["fwd"]["r"][:, :, mid - 1], stats, parents)
        pb = fk_positions(res["bwd"]["q"][:, :, max_length - 1 - mid], res["bwd"]["r"][:, :, max_length - 1 - mid],
                          stats, parents)
        extra = {"mid_f": pf, "mid_b": pb}
    return {"q": out["q"][:, :, 1:max_length], "r": out["r"][:, :, 1:max_length], **extra}


def sample_transitions(cfg, state, windows, n_past: int, n_trans: int, num_samples: int, seed: int = 0,
                       chunk: int = 128, velocity: bool = False, bank: TransitionBank | None = None,
                       blend_bank: bool = True, gate: tuple | None = None, forward_axis=None,
                       sampled: bool = True) -> dict:
    """Transitions between frame ``n_past - 1`` and frame ``n_past + n_trans`` of every window.
    ``velocity`` (models trained with ``start_velocity`` / ``base_velocity``, protocols with more than one past
    frame): the start keyframe carries frame ``n_past - 2`` (root displacement ``v``, local quaternions ``qp``).
    ``bank`` (with ``cfg.bank_k`` / ``cfg.bank_weight`` on): the samples are blended with the bank's
    transition (:func:`.bank.blend`; mid_f / mid_b stay the network's; ``blend_bank=False``: not blended); with
    ``cfg.bank_base`` that transition is also the network's residual base (:func:`.bank.knn_base_path`).  The
    bank is searched once; its transition is returned too (``bank_q`` (B, n_trans, J, 4), ``bank_r``).
    ``gate`` ((ContextBank, Gate), with ``cfg.ood_gate``): the samples are then moved toward Slerp / lerp by the
    out-of-distribution gate (:mod:`.gate`; ``forward_axis``: the root's facing axis), and ``ood_score`` /
    ``gate_weight`` (B,) are returned.  Last, with ``cfg.bank_sample_weight`` > 0, more than one sample and
    ``sampled``, the sampled mode (:func:`bank_samples`): sample s >= 1 moves toward the bank's s-th nearest
    transition; sample 0 stays the deterministic fill.

    cfg: ModelConfig; state: train state (``params``, ``stats``).
    Returns q (S, B, n_trans, J, 4), r (S, B, n_trans, 3) and, for the bi-directional model, mid_f / mid_b
    (S, B, J, 3) raw forward / backward FK positions at the middle frame.
    """
    length = n_trans + 1
    if cfg.bank_base and bank is None:
        raise ValueError("this S-CVAE was trained on the transition bank's base (model.bank_base): pass its bank")
    use_bank = bank is not None and bank_searched(cfg)
    if use_bank:            # one search for the residual base and the blend
        kq, kr = bank_transitions(bank, cfg, windows, n_past, n_trans)
    keys = jax.random.split(jax.random.key(seed), num_samples)
    parts = []
    k0, k1 = n_past - 1, n_past + n_trans
    for lo in range(0, len(windows), chunk):
        sl = slice(lo, lo + chunk)
        start = {"q": windows.local_quats[sl, k0], "r": windows.root_pos[sl, k0], "c": windows.contacts[sl, k0]}
        target = {"q": windows.local_quats[sl, k1], "r": windows.root_pos[sl, k1], "c": windows.contacts[sl, k1]}
        if velocity and cfg.uses_past_frame and n_past >= 2:
            start["v"] = windows.root_pos[sl, k0] - windows.root_pos[sl, k0 - 1]
            start["qp"] = windows.local_quats[sl, k0 - 1]
        if use_bank and cfg.bank_base:
            start["base_q"], start["base_r"] = pad_base_path(start["q"], start["r"], target["q"], target["r"],
                                                             kq[sl], kr[sl], length)
        start = jax.tree.map(jnp.asarray, start)
        target = jax.tree.map(jnp.asarray, target)
        parts.append(jax.device_get(_sample_chunk(state["params"], state["stats"], start, target, keys, cfg,
                                                  length, tuple(windows.parents))))
    out = {k: np.concatenate([p[k] for p in parts], axis=1) for k in parts[0]}
    if use_bank:
        out["bank_q"], out["bank_r"] = kq, kr
        if bank_enabled(cfg) and blend_bank:
            out["q"], out["r"] = blend(out["q"], out["r"], kq, kr, cfg.bank_weight)
    if gate is not None and cfg.ood_gate:
        from inbetween_jax.models.scvae.gate import gate_windows
        out["q"], out["r"], out["ood_score"], out["gate_weight"] = gate_windows(gate, windows, k0, k1, out["q"],
                                                                               out["r"], forward_axis)
    if sampled and bank is not None and sampled_mode(cfg, num_samples):
        out["q"], out["r"] = bank_samples(bank, cfg, windows, n_past, n_trans, out["q"], out["r"],
                                          out.get("gate_weight"))
    return out


def bank_samples(bank: TransitionBank, cfg, windows, n_past: int, n_trans: int, q, r, gate_weight=None,
                 spread=None):
    """The sampled mode (:func:`.bank.sample_blend`, ``cfg.bank_sample_weight``) on samples q (S, B, n_trans, J,
    4), r (S, B, n_trans, 3) of the transitions between frames ``n_past - 1`` and ``n_past + n_trans``: sample
    s >= 1 blended with the bank's s-th nearest transition (weight :func:`sample_weight`, ``gate_weight`` (B,)
    the gate's per window), then retimed at ``spread`` (default :func:`.bank.sample_timing_spread`, the two-keyframe
    one; inside a clip ``cfg.timing_spread_in_clip``)."""
    k0, k1 = n_past - 1, n_past + n_trans
    return bank_sample_blend(bank, windows.local_quats[:, k0], windows.root_pos[:, k0], windows.local_quats[:, k1],
                             windows.root_pos[:, k1], q, r, sample_weight(cfg, gate_weight),
                             sample_timing_spread(cfg, gate_weight) if spread is None else spread,
                             body_parts(windows.skeleton) if cfg.timing_parts else None)


def bank_transitions(bank: TransitionBank, cfg, windows, n_past: int, n_trans: int):
    """The bank's transitions (:func:`.bank.knn_transition`, ``cfg.bank_k`` / ``cfg.bank_tau``) between frames
    ``n_past - 1`` and ``n_past + n_trans`` of every window: q (B, n_trans, J, 4), r (B, n_trans, 3)."""
    k0, k1 = n_past - 1, n_past + n_trans
    return knn_transition(bank, windows.local_quats[:, k0], windows.root_pos[:, k0], windows.local_quats[:, k1],
                          windows.root_pos[:, k1], n_trans, cfg.bank_k, cfg.bank_tau)[:2]


# ----------------------------------------------------------------------------- users' keyframes
@functools.partial(jax.jit, static_argnames=("cfg", "max_length"))
def _sample_pair(params, stats, start, target, keys, cfg, max_length):
    out = M.sample(params, cfg, stats, start, target, max_length, keys, max_length)["out"]
    return out["q"][:, 0], out["r"][:, 0]


def infill_between(trained: Trained, skeleton, start: dict, end: dict, frames: int, num_samples: int,
                   seed: int = 0, forward_axis=None) -> dict:
    """Sample ``num_samples`` transitions of ``frames`` frames between two world-space keyframes.

    start / end: dicts with ``q`` (J, 4) unit local quaternions, ``r`` (3,) root position, ``c`` (4,) foot
    contacts; ``start`` may also carry the frame before it, ``qp`` (J, 4) and ``rp`` (3,), which models trained
    with the past frame (``ModelConfig.uses_past_frame``) continue; with ``model.context_base`` the fill follows
    the Hermite path through the motion on each side that carries two frames (``start``: ``qp``, ``rp``, ``qp2``,
    ``rp2``, the frames before it, nearest first; ``end``: ``qn``, ``rn``, ``qn2``, ``rn2``; :mod:`.context`).
    skeleton: the keyframes' skeleton (its offsets give the FK of the canonicalisation).
    forward_axis: the root's local facing axis (default: inferred from ``skeleton``).
    Returns ``q`` (S, frames + 2, J, 4) and ``r`` (S, frames + 2, 3) float64 in the keyframes' world space;
    frame 0 is ``start`` and frame ``frames + 1`` is ``end``, both exactly as given; ``context``: which
    neighbouring frames the fill continues (:func:`~.context.context_kind`); ``timing_by_part`` (S, len(PARTS)):
    each sample's retiming amplitude per body part (:func:`~.timing.retimed`; zeros when not retimed) and
    ``timing_shift`` (S,) the largest of them in size, signed; and with the gate ``ood_score`` and
    ``gate_weight``.

    Raises:
        ValueError: (one line naming the array) frames out of range, non-unit quaternions, bad root positions.
    """
    from inbetween_jax.data.user_input import check_unit_quats
    from inbetween_jax.data.windows import canonicalize
    from inbetween_jax.geometry import quat_fix_sign_np, quat_inv, quat_mul, quat_rotate
    lo, hi = frame_range(trained.cfg)
    if not lo <= frames <= hi:
        raise ValueError(f"frames={frames}: this S-CVAE generates {lo}..{hi} frames between keyframes")
    if num_samples < 1:
        raise ValueError(f"num_samples={num_samples}: need at least one sample")
    qs = check_unit_quats(start["q"], "start keyframe q")
    qe = check_unit_quats(end["q"], "end keyframe q")
    for name, key in (("start", start), ("end", end)):
        r = np.asarray(key["r"], np.float64)
        if r.shape != (3,) or not np.all(np.isfinite(r)):
            raise ValueError(f"{name} keyframe r: expected 3 finite numbers, got {r!r}")
    fa = np.asarray(skeleton.forward_axis() if forward_axis is None else forward_axis, np.float64)
    roots = np.stack([start["r"], end["r"]]).astype(np.float64)
    cq, cr = canonicalize(np.stack([qs, qe])[None], roots[None], skeleton, 1, fa)      # (1, 2, J, 4), (1, 2, 3)
    yaw = quat_mul(qs[0], quat_inv(cq[0, 0, 0]))                                      # canonical -> world
    shift = np.array([roots[:, 0].mean(), 0.0, roots[:, 2].mean()])
    frame = lambda i, c: {"q": jnp.asarray(cq[:, i], jnp.float32), "r": jnp.asarray(cr[:, i], jnp.float32),  # noqa
                          "c": jnp.asarray(np.asarray(c, np.float32)[None])}
    first = frame(0, start["c"])
    if trained.cfg.model.uses_past_frame and "qp" in start:
        first.update(past_frame_inputs(start, yaw, cq[0, 0]))
    m = trained.cfg.model
    if trained.bank is not None and m.bank_base:      # the residual base, in the canonical space
        first.update(zip(("base_q", "base_r"), map(jnp.asarray, knn_base_path(
            trained.bank, cq[:, 0], cr[:, 0], cq[:, 1], cr[:, 1], frames + 1, frames + 1, m.bank_k, m.bank_tau))))
    keys = jax.random.split(jax.random.key(seed), num_samples)
    q, r = jax.device_get(_sample_pair(trained.params, trained.stats, first, frame(1, end["c"]),
                                       keys, trained.cfg.model, frames + 1))
    q, r = np.asarray(q, np.float64)[:, :frames + 2], np.asarray(r, np.float64)[:, :frames + 2]
    q[:, :, 0] = quat_mul(np.broadcast_to(yaw, q[:, :, 0].shape), q[:, :, 0])
    r = quat_rotate(np.broadcast_to(yaw, r.shape[:-1] + (4,)), r) + shift
    if trained.bank is not None and bank_enabled(m):
        kq, kr, _ = knn_transition(trained.bank, qs[None], roots[:1], qe[None], roots[1:], frames, m.bank_k,
                                   m.bank_tau)
        mid_q, mid_r = blend(q[:, None, 1:-1], r[:, None, 1:-1], kq, kr, m.bank_weight)
        q[:, 1:-1], r[:, 1:-1] = mid_q[:, 0], mid_r[:, 0]
    gated = {}
    ctx = context_kind(start, end) if m.context_base else "none"
    if trained.gate is not None and m.ood_gate:   # toward Slerp / lerp as the keyframes leave the training motion
        from inbetween_jax.models.scvae.gate import gate_pairs
        gate = trained.gate
        if ctx != "none" and trained.context_gate is not None and m.context_gate:   # thresholds for that base
            gate = (gate[0], trained.context_gate)
        mid_q, mid_r, score, weight = gate_pairs(gate, qs[None], roots[:1], qe[None], roots[1:], skeleton, fa,
                                                 q[:, None, 1:-1], r[:, None, 1:-1])
        q[:, 1:-1], r[:, 1:-1] = mid_q[:, 0], mid_r[:, 0]
        gated = {"ood_score": float(score[0]), "gate_weight": float(weight[0])}
        if gate is not trained.gate:      # the sampled mode keeps the two-keyframe gate's weight (docs: gate.md)
            gated["sample_gate_weight"] = float(trained.gate[1].weight(score)[0])
    if ctx != "none":                # the departure from Slerp / lerp onto the Hermite path through the neighbours
        from inbetween_jax.models.scvae.gate import slerp_base
        before, after = known_sides(start, end)
        if m.base_velocity and "qp" in start:     # the network's own base continues the start's motion already
            before = None
        nb = neighbours(m, skeleton, qs[None], roots[:1], qe[None], roots[1:], before, after)
        dq, dr = context_offsets(qs[None], roots[:1], qe[None], roots[1:], frames, m.context_damping, *nb)
        mid_q, mid_r = onto_context(q[:, None, 1:-1], r[:, None, 1:-1],
                                    *slerp_base(qs[None], roots[:1], qe[None], roots[1:], frames), dq, dr)
        q[:, 1:-1], r[:, 1:-1] = mid_q[:, 0], mid_r[:, 0]
    timing = np.zeros((num_samples, len(PARTS)))
    if trained.bank is not None and sampled_mode(m, num_samples):   # sample s >= 1: the bank's s-th nearest
        spread = (sample_timing_spread(m, _sample_gate(gated)) if ctx == "none"
                  else m.timing_spread_in_clip)                                # the sides pin the timing more
        mid_q, mid_r = bank_sample_blend(trained.bank, qs[None], roots[:1], qe[None], roots[1:], q[:, None, 1:-1],
                                         r[:, None, 1:-1], sample_weight(m, _sample_gate(gated)), spread,
                                         body_parts(skeleton) if m.timing_parts else None)
        q[:, 1:-1], r[:, 1:-1] = mid_q[:, 0], mid_r[:, 0]
        if spread > 0:                                               # as bank_sample_blend retimes
            timing = part_amplitudes(num_samples, spread, m.timing_parts)
    q[:, 0], r[:, 0], q[:, -1], r[:, -1] = qs, roots[0], qe, roots[1]                 # exact keyframes
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    biggest = np.take_along_axis(timing, np.abs(timing).argmax(1)[:, None], 1)[:, 0]
    return {"q": quat_fix_sign_np(q, axis=1), "r": r, **gated, "context": ctx, "timing_shift": biggest,
            "timing_by_part": timing}


def _is_lafan1_skeleton(skel) -> bool:
    return skel.names[0] == "Hips" and "LeftToe" in skel.names


def infill(args, run):
    """``inbetween infill --model scvae``: ``args.samples`` transitions of ``args.frames`` frames from
    ``args.start`` to ``args.end`` (``FILE.bvh[:FRAME]``) on the start file's skeleton.

    Returns an :class:`~inbetween_jax.models.spec.InfillResult` with one Motion per sample (``sample_00`` ...):
    frames + 2 frames, the start keyframe, the generated frames and the end keyframe.  Keyframe files at another
    frame rate are resampled to the checkpoint's (FRAME counts the file's frames, rounded to the nearest
    resampled one; ``--frames`` counts the checkpoint's) and larger rigs matched by name
    (:mod:`inbetween_jax.data.retarget`); the samples are at the checkpoint's rate on the start file's rig.
    Raises:
        UserError: one line naming the file / option (unreadable BVH, other skeleton, frames out of range, a
            diverged checkpoint).
    """
    from inbetween_jax.data import lafan1
    from inbetween_jax.data.datasets import GENERIC_CONTACT_VELFACTOR
    from inbetween_jax.data.retarget import prepare, to_frame
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
    toward = float(sample_weight(m, _sample_gate(gated))) if sampling else 0.0   # samples 1.. toward capture
    if gated:
        from inbetween_jax.models.ood import gate_note
        notes.append(gate_note(gated["ood_score"], gated["gate_weight"],
                               "Slerp / lerp" if context == "none" else "the Hermite path"))
        if sampling and m.bank_sample_gated and _sample_gate(gated) < 0.5:
            notes.append(f"the {args.samples} samples stay close to the fill: the keyframes lie outside the captured "
                         f"motion the samples draw on (sampled-mode weight {toward:.2f})")
    t = args.frames + 2
    w = (np.arange(t) / (t - 1))[:, None, None]
    base_pos = (1 - w) * sm.local_pos[sf] + w * em.local_pos[ef]       # joints with position channels: lerp
    # the user's rig: keyframes at both ends (frame ef is the end file's), the rest from the generated motion
    keys = ps.end_keys(sf, pe, ef, t) if ps.on_other_rig else None
    samples = []
    for name, q, r in zip(sample_names(args.samples), res["q"], res["r"]):
        pos = base_pos.copy()
        pos[:, 0] = r
        out = dataclasses.replace(sm, local_quats=q, local_pos=pos)
        samples.append((name, [ps.on_user_rig(out, keys)], None))
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
