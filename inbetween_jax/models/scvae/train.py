"""S-CVAE training: data loading, batches with progressive transition length, the pure train step and
:func:`make_training` for :func:`inbetween_jax.runner.train_model`.

Batch (dict of arrays; T1 = max_length + 1 frames in forward time, frames after ``length`` repeat the
target keyframe): q (B, T1, J, 4), r (B, T1, 3), c (B, T1, 4), phase_f / phase_b (B, T1, 4) local-phase
labels of the forward / reversed motion (both stored in forward time), p (B, T1, J, 3) global positions,
length () int32 = frames between the two keyframes (L = transition length + 1); with ``model.bank_base`` also
base_q (B, T1, J, 4), base_r (B, T1, 3): the residual base from the bank (:func:`.bank.knn_base_path`).

Train state: ``{"params": {"fwd", "bwd"}, "disc": {"long", "short"}, "opt_g", "opt_d", "stats"}`` (plain
nested dicts of arrays; ``stats`` is :func:`~inbetween_jax.models.scvae.features.compute_stats`).
"""
from __future__ import annotations

import dataclasses
import os

import jax
import jax.numpy as jnp
import numpy as np
import optax

from inbetween_jax.models.scvae import losses as L
from inbetween_jax.models.scvae import model as M
from inbetween_jax.models.scvae import motion_latent as ML
from inbetween_jax.data.windows import MotionWindows
from inbetween_jax.models.scvae.bank import BANK_FILE, TransitionBank, check_mirror, knn_base_path
from inbetween_jax.models.scvae.deferred_grads import add_deferred_weight_grads, make_taps
from inbetween_jax.models.scvae.features import TrainData, compute_stats, dims
from inbetween_jax.models.spec import Training
from inbetween_jax.train.optim import make_optimizer
from inbetween_jax.train.remat import check_remat

__all__ = ["load_data", "make_training", "make_init_fn", "make_train_step", "batch_fn_factory", "make_batch",
           "group_weights", "split_batch", "generator_loss", "transition_length", "scan_length"]


def load_data(cfg, source: str, split: str = "train") -> TrainData:
    """Windows of ``split`` of ``source`` (a LaFAN1 / BVH folder or ``"embedded"``) with phase labels and
    feature statistics (``data.stats``).

    Raises:
        ValueError: the windows are too short for ``data.trans_max`` (one line naming the source).
    """
    from inbetween_jax.data import load_dataset
    from inbetween_jax.data.datasets import is_lafan1, split_files, window_settings
    windows = load_dataset(source, split, window=cfg.data.window or None)
    if cfg.data.trans_max + 2 + int(cfg.model.uses_past_frame) > windows.window:
        raise ValueError(f"{source}: {windows.window}-frame {split} windows are too short for "
                         f"data.trans_max={cfg.data.trans_max} (at most {windows.window - 2})")
    ws = window_settings(source, split)
    forward = ws["forward_axis"] or tuple(windows.skeleton.forward_axis())
    windows = _with_tempo_copies(windows, source, split, cfg.data.tempo)
    if cfg.data.mirror:
        check_mirror(windows.skeleton, forward, source, "data.mirror")
        windows = MotionWindows.concatenate([windows, windows.mirrored()])
    bank = None
    if cfg.model.bank_base:
        if not cfg.model.residual or cfg.model.bank_k < 1:
            raise ValueError("model.bank_base needs model.residual=true and model.bank_k >= 1")
        from inbetween_jax.data import load_motions
        bank = TransitionBank.from_motions(load_motions(source, split), np.asarray(forward, np.float64))
        bank.cache_lengths = cfg.data.trans_max + 1
    return TrainData.from_windows(
        windows, stats=compute_stats(windows),
        provenance={"source": source, "split": split,
                    "files": [os.path.basename(f) for f in split_files(source, split)],
                    "windows": len(windows), "window_frames": windows.window},
        extra={"lafan1": bool(is_lafan1(source)), "forward_axis": [float(x) for x in forward],
               "contact_velfactor": float(ws["contact_velfactor"])}, bank=bank)


def _with_tempo_copies(windows: MotionWindows, source: str, split: str, tempo) -> MotionWindows:
    """``windows`` plus, for each speed ``s`` of ``tempo`` (``data.tempo``), the split's files read at
    ``fps / s`` and played at ``fps``: the same real motion ``s`` times faster.

    Raises:
        ValueError: a speed that is not positive (one line).
    """
    if not tempo:
        return windows
    from inbetween_jax.data import load_dataset
    from inbetween_jax.data.resample import check_tempo
    copies = [dataclasses.replace(load_dataset(source, split, window=windows.window, fps=windows.fps / s),
                                  fps=windows.fps) for s in check_tempo(tempo)]
    return MotionWindows.concatenate([windows] + copies)


def make_training(cfg, data: TrainData) -> Training:
    """init / step / batch functions and run metadata for :func:`inbetween_jax.train.run_training`."""
    max_length = cfg.data.trans_max + 1
    if data.stats is None:
        raise ValueError("make_training needs the data of load_data (with its feature statistics)")
    stats, num_joints = data.stats, int(data.q.shape[2])
    meta = {"skeleton": data.skeleton.to_dict() if data.skeleton is not None else None, "fps": data.fps,
            "stats": stats, "data": dict(data.provenance), "extra": {"num_joints": num_joints, **data.extra}}
    src = data.provenance.get("source")
    describe = (f"{len(data)} windows of {data.q.shape[1]} frames{f' from {src}' if src else ''} ({num_joints} "
                f"joints); transitions of {cfg.data.trans_start}..{cfg.data.trans_max} frames")
    files = {}
    if data.bank is not None:     # model.bank_base: the run folder keeps the bank its base came from
        files[BANK_FILE] = data.bank.save
        describe += f"; residual base: the {cfg.model.bank_k} nearest of {data.bank.num_frames} bank frames"
    return Training(init_fn=make_init_fn(cfg, stats, num_joints),
                    step_fn=make_train_step(cfg, data.parents, max_length),
                    batch_fn=batch_fn_factory(data, cfg), num_steps=cfg.train.num_steps, meta=meta,
                    describe=describe, files=files)


def transition_length(step: int, cfg, num_windows: int) -> int:
    """Progressive training: ``data.trans_start`` + 1 every ``data.epochs_per_increment`` epochs (an epoch:
    ``num_windows // train.batch_size`` steps), capped at ``data.trans_max``; with ``data.ramp_steps`` > 0
    the same ramp runs linearly over that many steps instead.  cfg: Config."""
    dcfg = cfg.data
    if dcfg.ramp_steps > 0:
        frac = min(1.0, step / dcfg.ramp_steps)
        return int(round(dcfg.trans_start + frac * (dcfg.trans_max - dcfg.trans_start)))
    steps_per_epoch = max(1, num_windows // cfg.train.batch_size)
    inc = int(step // max(1.0, dcfg.epochs_per_increment * steps_per_epoch))
    return int(min(dcfg.trans_max, dcfg.trans_start + inc))


def scan_length(length: int, cfg) -> int:
    """Static rollout length (frames between keyframes) of a batch whose keyframes are ``length`` apart:
    ``trans_max + 1`` (paper: one shape) or, with ``data.bucket`` > 0, ``length`` rounded up to a multiple of
    the bucket, so short stages of the progressive schedule run shorter scans (one compile per bucket)."""
    top = cfg.data.trans_max + 1
    if cfg.data.bucket <= 0:
        return top
    return int(min(top, -(-length // cfg.data.bucket) * cfg.data.bucket))


def make_batch(data: TrainData, idx: np.ndarray, starts: np.ndarray, length: int, max_length: int,
               velocity: bool = False) -> dict:
    """Cut frames start..start+length of windows idx, padded to max_length+1 frames with the target.
    ``velocity``: also ``v0`` (B, 3), the root velocity into the start keyframe (start - previous frame)."""
    t = np.minimum(np.arange(max_length + 1)[None, :], length) + starts[:, None]   # (B, T1)
    rows = idx[:, None]
    batch = {"q": data.q[rows, t], "r": data.r[rows, t], "c": data.c[rows, t],
             "phase_f": data.phase_f[rows, t], "phase_b": data.phase_b[rows, t], "p": data.p[rows, t],
             "length": np.int32(length)}
    if velocity:   # the frame before the start keyframe: root displacement and local quaternions
        batch["v0"] = data.r[idx, starts] - data.r[idx, starts - 1]
        batch["qp0"] = data.q[idx, starts - 1]
    return batch


def batch_fn_factory(data: TrainData, cfg):
    """``(step, key) -> batch`` deterministic in its arguments (run_training's contract).  cfg: Config."""
    max_length = cfg.data.trans_max + 1
    window = data.q.shape[1]
    if max_length >= window:
        raise ValueError(f"data.trans_max={cfg.data.trans_max} needs windows of at least {max_length + 1} frames "
                         f"(these have {window})")
    batch_size = cfg.train.batch_size

    vel = cfg.model.uses_past_frame
    bank = data.bank
    weights = group_weights(data.names, cfg.data.balance) if cfg.data.balance else None
    own_clip = bank.clip_of([n.split("@", 1)[0] for n in data.names]) if bank is not None else None

    def batch_fn(step, key):
        seed = np.asarray(jax.random.key_data(key)).astype(np.uint64)
        rng = np.random.default_rng(seed)
        length = transition_length(step, cfg, len(data)) + 1
        if cfg.data.length_mode == "mixed":   # any length up to the current maximum, one per batch
            length = int(rng.integers(cfg.data.trans_start + 1, length + 1))
        idx = rng.choice(len(data), batch_size, p=weights) if weights is not None else rng.integers(0, len(data),
                                                                                                      batch_size)
        starts = rng.integers(int(vel), window - length, batch_size)
        batch = make_batch(data, idx, starts, length, scan_length(length, cfg), vel)
        if bank is not None:      # the window's own file is never retrieved: the bank as on unseen motion
            m = cfg.model
            batch["base_q"], batch["base_r"] = knn_base_path(
                bank, batch["q"][:, 0], batch["r"][:, 0], batch["q"][:, length], batch["r"][:, length], length,
                batch["q"].shape[1] - 1, m.bank_k, m.bank_tau, exclude=own_clip[idx])
        return batch

    return batch_fn


def group_weights(names, balance: float) -> np.ndarray:
    """Sampling probabilities of training windows named ``names`` (``"<file stem>@<frame>"``): each window
    weighs ``n_g ** -balance``, ``n_g`` the number of windows of its activity group (``data.balance``)."""
    from collections import Counter

    from inbetween_jax.data.activities import activity_group
    groups = [activity_group(n.split("@", 1)[0]) for n in names]
    count = Counter(groups)
    w = np.array([count[g] ** -float(balance) for g in groups], np.float64)
    return w / w.sum()


def split_batch(batch: dict):
    """Keyframes and the ground truth in forward and backward (reversed) time."""
    length = batch["length"]
    t1 = batch["q"].shape[1]
    take = lambda x, i: jnp.take(x, i, axis=1)
    start = {"q": batch["q"][:, 0], "r": batch["r"][:, 0], "c": batch["c"][:, 0]}
    if "v0" in batch:
        start["v"], start["qp"] = batch["v0"], batch["qp0"]
    if "base_q" in batch:     # model.bank_base: the residual decoder's base path
        start["base_q"], start["base_r"] = batch["base_q"], batch["base_r"]
    target = {"q": take(batch["q"], length), "r": take(batch["r"], length), "c": take(batch["c"], length)}
    gt_f = {"q": batch["q"], "r": batch["r"], "c": batch["c"], "phase": batch["phase_f"], "p": batch["p"]}
    rev = jnp.clip(length - jnp.arange(t1), 0, t1 - 1)
    gt_b = {"q": take(batch["q"], rev), "r": take(batch["r"], rev), "c": take(batch["c"], rev),
            "phase": take(batch["phase_b"], rev), "p": take(batch["p"], rev)}
    return start, target, gt_f, gt_b


def make_init_fn(cfg, stats: dict, num_joints: int):
    """key -> train state {params, disc, opt_g, opt_d, stats}."""
    opt = make_optimizer(cfg.train)

    def init_fn(key):
        kg, kd = jax.random.split(key)
        params = M.init_params(kg, cfg.model, num_joints)
        disc = L.init_discriminators(kd, cfg.model, dims(num_joints)["state"])
        return {"params": params, "disc": disc, "opt_g": opt.init(params), "opt_d": opt.init(disc),
                "stats": jax.tree.map(jnp.asarray, stats)}

    return init_fn


def generator_loss(params, disc, cfg, stats, batch, key, parents, max_length, taps=None):
    """Eq. 10 without the discriminator term.  Returns (loss, (metrics, stitched output, recorded matmul
    inputs)); with ``taps`` (:func:`.deferred_grads.make_taps`) the tapped weights get no gradient here (see
    :func:`.deferred_grads.add_deferred_weight_grads`)."""
    mcfg, lcfg = cfg.model, cfg.loss
    start, target, gt_f, gt_b = split_batch(batch)
    length = batch["length"]
    motion, m = None, {}
    if mcfg.motion_latent:   # the transition's motion latent from the posterior, which sees the true gap
        base_q, base_r = M.base_path(start, target, length, max_length, mcfg.base_velocity, mcfg.base_damping)
        mp = params["fwd"]["motion"]
        post = ML.posterior(mp, stats, gt_f, base_q, base_r, length)
        motion = ML.draw(*post, jax.random.fold_in(key, 1))
        prior = ML.prior(mp, stats, start, target, length, mcfg.tta_max)
        motion_term, m["kl_motion"] = ML.motion_kl_terms(post, prior, lcfg.motion_free_bits)
        if lcfg.prior_path:   # the same windows again from the prior's mean: the zero-temperature fill stays accurate
            start, target, gt_f, gt_b = (jax.tree.map(lambda x: jnp.concatenate([x, x]), d)
                                         for d in (start, target, gt_f, gt_b))
            motion = jnp.concatenate([motion, prior[0]])
    res = M.rollout(params, mcfg, stats, start, target, length, key, max_length, taps, motion)
    if mcfg.bidirectional:   # one FK call for both generators
        both = L.fk_positions(jnp.concatenate([res["fwd"]["q"], res["bwd"]["q"]]),
                              jnp.concatenate([res["fwd"]["r"], res["bwd"]["r"]]), stats, parents)
        pos_f, pos_b = jnp.split(both, 2)
    else:
        pos_f = L.fk_positions(res["fwd"]["q"], res["fwd"]["r"], stats, parents)
    lf = L.direction_losses(res["fwd"], pos_f, res["kl_fwd"], res["valid"], gt_f, stats, lcfg)
    ph = L.phase_loss(params["fwd"]["phase"], gt_f, length, stats)
    if mcfg.bidirectional:
        lb = L.direction_losses(res["bwd"], pos_b, res["kl_bwd"], res["valid"], gt_b, stats, lcfg)
        ph = 0.5 * (ph + L.phase_loss(params["bwd"]["phase"], gt_b, length, stats))
        d = {n: 0.5 * (lf[n] + lb[n]) for n in ("state", "kl", "kl_term", "fk")}
        stitch = L.stitch_loss(pos_f, pos_b, length, res["h"], res["k"], stats["pos_unit"])
    else:
        d = {n: lf[n] for n in ("state", "kl", "kl_term", "fk")}
        stitch = jnp.float32(0.0)
    loss = d["state"] + lcfg.alpha_kl * d.pop("kl_term") + lcfg.alpha_fk * d["fk"] + lcfg.phase * ph
    if mcfg.bidirectional and mcfg.stitch_loss:
        loss = loss + lcfg.alpha_stitch * stitch
    if motion is not None:
        loss = loss + lcfg.alpha_motion * motion_term
    lg = jnp.float32(0.0)
    if mcfg.discriminators:
        fake = L.disc_features(res["out"], stats)
        real = L.disc_features(gt_f, stats)
        lg, _ = L.lsgan_losses(jax.lax.stop_gradient(disc), mcfg, fake, real, length)
        loss = loss + lcfg.alpha_g * lg
    m.update(d, stitch=stitch, phase=ph, g_adv=lg, loss=loss)
    recs = {g: res[f"rec_{g}"] for g in ("fwd", "bwd") if f"rec_{g}" in res}
    return loss, (m, res["out"], recs)


def make_train_step(cfg, parents: tuple, max_length: int | None = None):
    """Pure ``(state, batch, key) -> (state, metrics)``; the rollout length comes from the batch's shape
    (``max_length`` is accepted for callers that pass it and is not used)."""
    check_remat(cfg.model.remat)
    opt = make_optimizer(cfg.train)

    def train_step(state, batch, key):
        stats = state["stats"]
        max_length = batch["q"].shape[1] - 1   # static: one compile per scan bucket (:func:`scan_length`)
        if cfg.model.deferred_wgrad:   # largest weight gradients as one matmul each after the scan
            rows = batch["q"].shape[0] * (2 if cfg.model.motion_latent and cfg.loss.prior_path else 1)
            taps = make_taps(state["params"], cfg.model, rows, M.num_scan_steps(cfg.model, max_length))
            grad_fn = jax.value_and_grad(generator_loss, argnums=(0, 8), has_aux=True)
            (loss, (metrics, out, recs)), (g, g_taps) = grad_fn(state["params"], state["disc"], cfg, stats, batch,
                                                                key, parents, max_length, taps)
            g = add_deferred_weight_grads(g, recs, g_taps)
        else:
            grad_fn = jax.value_and_grad(generator_loss, has_aux=True)
            (loss, (metrics, out, _)), g = grad_fn(state["params"], state["disc"], cfg, stats, batch, key, parents,
                                                   max_length)
        upd, opt_g = opt.update(g, state["opt_g"], state["params"])
        params = optax.apply_updates(state["params"], upd)
        disc, opt_d = state["disc"], state["opt_d"]
        if cfg.model.discriminators:
            fake = L.disc_features(jax.lax.stop_gradient(out), stats)
            real = L.disc_features({"q": batch["q"], "r": batch["r"], "c": batch["c"]}, stats)

            def d_loss(dp):
                return cfg.loss.alpha_d * L.lsgan_losses(dp, cfg.model, fake, real, batch["length"])[1]

            ld, gd = jax.value_and_grad(d_loss)(disc)
            upd_d, opt_d = opt.update(gd, opt_d, disc)
            disc = optax.apply_updates(disc, upd_d)
            metrics["d_adv"] = ld / cfg.loss.alpha_d
        else:
            metrics["d_adv"] = jnp.float32(0.0)
        metrics["length"] = batch["length"].astype(jnp.float32)
        return dict(state, params=params, disc=disc, opt_g=opt_g, opt_d=opt_d), metrics

    return train_step
