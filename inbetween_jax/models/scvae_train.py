"""S-CVAE training: statistics, batches with progressive transition length, the pure train step and
``train()`` on top of :func:`inbetween_jax.train.run_training`.

Batch (dict of arrays; T1 = max_length + 1 frames in forward time, frames after ``length`` repeat the
target keyframe): q (B, T1, J, 4), r (B, T1, 3), c (B, T1, 4), phase_f / phase_b (B, T1, 4) local-phase
labels of the forward / reversed motion (both stored in forward time), length () int32 = frames between
the two keyframes (L = transition length + 1).
"""
from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import optax

from inbetween_jax.data import l2p_stats
from inbetween_jax.models import scvae
from inbetween_jax.models import scvae_losses as L
from inbetween_jax.models.scvae_phase import phase_labels


def compute_stats(windows) -> dict:
    """Feature scales from training windows (MotionWindows): v_std (3,), off_std (3,), pos_unit (),
    offsets (J, 3)."""
    r = windows.root_pos.astype(np.float64)
    v = r[:, 1:] - r[:, :-1]
    off = r[:, None, :, :] - r[:, :, None, :]
    _, gp = windows.global_pose()
    _, x_std = l2p_stats(gp)
    return {"v_std": np.maximum(v.reshape(-1, 3).std(0), 1e-2).astype(np.float32),
            "off_std": np.maximum(np.sqrt((off ** 2).reshape(-1, 3).mean(0)), 1.0).astype(np.float32),
            "pos_unit": np.float32(x_std.mean()),
            "offsets": windows.offsets.astype(np.float32)}


@dataclasses.dataclass
class TrainData:
    """Training windows with their phase labels (NumPy)."""
    q: np.ndarray        # (N, T, J, 4)
    r: np.ndarray        # (N, T, 3)
    c: np.ndarray        # (N, T, 4)
    phase_f: np.ndarray  # (N, T, 4)
    phase_b: np.ndarray  # (N, T, 4)
    p: np.ndarray        # (N, T, J, 3) global joint positions
    parents: tuple

    @classmethod
    def from_windows(cls, w) -> "TrainData":
        pf = phase_labels(w.contacts)
        pb = phase_labels(w.reversed().contacts)[:, ::-1].copy()   # labelled on the reversed motion
        return cls(w.local_quats.astype(np.float32), w.root_pos.astype(np.float32), w.contacts.astype(np.float32),
                   pf, pb, w.global_pose()[1], tuple(w.parents))

    def __len__(self):
        return self.q.shape[0]


def transition_length(step: int, tcfg, num_windows: int) -> int:
    """Progressive training: trans_start + 1 every ``epochs_per_increment`` epochs, capped at trans_max."""
    steps_per_epoch = max(1, num_windows // tcfg.batch_size)
    inc = int(step // max(1.0, tcfg.epochs_per_increment * steps_per_epoch))
    return int(min(tcfg.trans_max, tcfg.trans_start + inc))


def make_batch(data: TrainData, idx: np.ndarray, starts: np.ndarray, length: int, max_length: int) -> dict:
    """Cut frames start..start+length of windows idx, padded to max_length+1 frames with the target."""
    t = np.minimum(np.arange(max_length + 1)[None, :], length) + starts[:, None]   # (B, T1)
    rows = idx[:, None]
    return {"q": data.q[rows, t], "r": data.r[rows, t], "c": data.c[rows, t],
            "phase_f": data.phase_f[rows, t], "phase_b": data.phase_b[rows, t], "p": data.p[rows, t],
            "length": np.int32(length)}


def batch_fn_factory(data: TrainData, tcfg):
    """``(step, key) -> batch`` deterministic in its arguments (run_training's contract)."""
    max_length = tcfg.trans_max + 1
    window = data.q.shape[1]
    if max_length >= window:
        raise ValueError(f"trans_max={tcfg.trans_max} needs windows of at least {max_length + 1} frames")

    def batch_fn(step, key):
        seed = np.asarray(jax.random.key_data(key)).astype(np.uint64)
        rng = np.random.default_rng(seed)
        length = transition_length(step, tcfg, len(data)) + 1
        idx = rng.integers(0, len(data), tcfg.batch_size)
        starts = rng.integers(0, window - length, tcfg.batch_size)
        return make_batch(data, idx, starts, length, max_length)

    return batch_fn


def split_batch(batch: dict):
    """Keyframes and the ground truth in forward and backward (reversed) time."""
    length = batch["length"]
    t1 = batch["q"].shape[1]
    take = lambda x, i: jnp.take(x, i, axis=1)
    start = {"q": batch["q"][:, 0], "r": batch["r"][:, 0], "c": batch["c"][:, 0]}
    target = {"q": take(batch["q"], length), "r": take(batch["r"], length), "c": take(batch["c"], length)}
    gt_f = {"q": batch["q"], "r": batch["r"], "c": batch["c"], "phase": batch["phase_f"], "p": batch["p"]}
    rev = jnp.clip(length - jnp.arange(t1), 0, t1 - 1)
    gt_b = {"q": take(batch["q"], rev), "r": take(batch["r"], rev), "c": take(batch["c"], rev),
            "phase": take(batch["phase_b"], rev), "p": take(batch["p"], rev)}
    return start, target, gt_f, gt_b


def make_optimizer(tcfg):
    return optax.chain(optax.clip_by_global_norm(tcfg.grad_clip),
                       optax.adamw(tcfg.lr, b1=tcfg.b1, b2=tcfg.b2, weight_decay=tcfg.weight_decay))


def make_init_fn(cfg, stats: dict, num_joints: int):
    """key -> train state {params, disc, opt_g, opt_d, stats}."""
    opt = make_optimizer(cfg.train)

    def init_fn(key):
        kg, kd = jax.random.split(key)
        params = scvae.init_params(kg, cfg.model, num_joints)
        disc = L.init_discriminators(kd, cfg.model, scvae.dims(num_joints)["state"])
        return {"params": params, "disc": disc, "opt_g": opt.init(params), "opt_d": opt.init(disc),
                "stats": jax.tree.map(jnp.asarray, stats)}

    return init_fn


def generator_loss(params, disc, cfg, stats, batch, key, parents, max_length, taps=None):
    """Eq. 10 without the discriminator term.  Returns (loss, (metrics, stitched output, recorded matmul
    inputs)); with ``taps`` (:func:`scvae.make_taps`) the tapped weights get no gradient here (see
    :func:`scvae.add_deferred_weight_grads`)."""
    mcfg, lcfg = cfg.model, cfg.loss
    start, target, gt_f, gt_b = split_batch(batch)
    length = batch["length"]
    res = scvae.rollout(params, mcfg, stats, start, target, length, key, max_length, taps)
    if mcfg.bidirectional:   # one FK call for both generators
        both = L.fk_positions(jnp.concatenate([res["fwd"]["q"], res["bwd"]["q"]]),
                              jnp.concatenate([res["fwd"]["r"], res["bwd"]["r"]]), stats, parents)
        pos_f, pos_b = jnp.split(both, 2)
    else:
        pos_f = L.fk_positions(res["fwd"]["q"], res["fwd"]["r"], stats, parents)
    lf = L.direction_losses(res["fwd"], pos_f, res["kl_fwd"], res["valid"], gt_f, stats, lcfg)
    ph = L.phase_loss(params["fwd"]["phase"], gt_f, length, stats)
    m = {}
    if mcfg.bidirectional:
        lb = L.direction_losses(res["bwd"], pos_b, res["kl_bwd"], res["valid"], gt_b, stats, lcfg)
        ph = 0.5 * (ph + L.phase_loss(params["bwd"]["phase"], gt_b, length, stats))
        d = {n: 0.5 * (lf[n] + lb[n]) for n in ("state", "kl", "fk")}
        stitch = L.stitch_loss(pos_f, pos_b, length, res["h"], res["k"], stats["pos_unit"])
    else:
        d = {n: lf[n] for n in ("state", "kl", "fk")}
        stitch = jnp.float32(0.0)
    loss = d["state"] + lcfg.alpha_kl * d["kl"] + lcfg.alpha_fk * d["fk"] + lcfg.phase * ph
    if mcfg.bidirectional and mcfg.stitch_loss:
        loss = loss + lcfg.alpha_stitch * stitch
    lg = jnp.float32(0.0)
    if mcfg.discriminators:
        fake = L.disc_features(res["out"], stats)
        real = L.disc_features(gt_f, stats)
        lg, _ = L.lsgan_losses(jax.lax.stop_gradient(disc), mcfg, fake, real, length)
        loss = loss + lcfg.alpha_g * lg
    m.update(d, stitch=stitch, phase=ph, g_adv=lg, loss=loss)
    recs = {g: res[f"rec_{g}"] for g in ("fwd", "bwd") if f"rec_{g}" in res}
    return loss, (m, res["out"], recs)


def make_train_step(cfg, parents: tuple, max_length: int):
    """Pure ``(state, batch, key) -> (state, metrics)``."""
    opt = make_optimizer(cfg.train)

    def train_step(state, batch, key):
        stats = state["stats"]
        if cfg.train.deferred_wgrad:   # largest weight gradients as one matmul each after the scan
            taps = scvae.make_taps(state["params"], cfg.model, batch["q"].shape[0], max_length)
            grad_fn = jax.value_and_grad(generator_loss, argnums=(0, 8), has_aux=True)
            (loss, (metrics, out, recs)), (g, g_taps) = grad_fn(state["params"], state["disc"], cfg, stats, batch,
                                                                key, parents, max_length, taps)
            g = scvae.add_deferred_weight_grads(g, recs, g_taps)
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


def train(cfg, windows, run_dir: str, num_steps: int | None = None, progress: bool = True):
    """Train on MotionWindows ``windows`` (forward time; the backward generator sees them reversed).
    Resumes from ``run_dir/checkpoints``.  Returns (state, logged rows)."""
    from inbetween_jax.train import run_training
    data = TrainData.from_windows(windows)
    stats = compute_stats(windows)
    max_length = cfg.train.trans_max + 1
    init_fn = make_init_fn(cfg, stats, data.q.shape[2])
    step_fn = make_train_step(cfg, data.parents, max_length)
    tc = cfg.train
    return run_training(init_fn, step_fn, batch_fn_factory(data, tc), cfg, run_dir,
                        num_steps if num_steps is not None else tc.num_steps, tc.log_every, tc.ckpt_every, tc.seed,
                        progress=progress)


def steps_for_epochs(epochs: float, num_windows: int, batch_size: int) -> int:
    return int(math.ceil(epochs * num_windows / batch_size))
