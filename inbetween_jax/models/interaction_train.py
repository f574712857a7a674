"""Training of the interaction in-betweening model: pure ``init_fn`` / ``train_step_fn`` / ``batch_fn`` for
:func:`inbetween_jax.train.run_training`.

Per step (Sec. 4.1.3 and 4.2): P autoregressive steps (``lax.scan``) with scheduled sampling;
``L = w_mse MSE + w_coarse MSE_coarse + w_kl KL + w_adv L_adv`` for the generator; the periodic autoencoder is
fitted to real pairwise-joint-distance dynamics (its own loss); the discriminator separates PAE latents of
real and generated N = P * l frame PJD dynamics; the refiner learns ``Refiner(pred) -> ground truth`` on the
(stop-gradient) predictions.  The parameter groups are disjoint and every group only receives gradients of
its own loss, so one Adam over all groups equals independent optimisers.

State: ``{"params": {gen, ref, pae, disc}, "opt": optax state, "step": int32}``.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import nnx

from inbetween_jax.models.interaction import generator_step, init_params, refine
from inbetween_jax.models.interaction_data import apply_space, sample_batch
from inbetween_jax.models.interaction_nets import kl_divergence, pjd_dynamics

BATCH_KEYS = ("x", "keypose", "rel_R", "rel_t")


def make_optimizer(cfg):
    return optax.chain(optax.clip_by_global_norm(cfg.train.grad_clip), optax.adam(cfg.train.lr))


def common_positions(feats, rel_R, rel_t):
    """Both characters' positions in character A's keyframe space: feats (B, 2, T, J, 9) -> two (B, T, J, 3)."""
    b_in_a = apply_space(feats[:, 1], rel_R[:, 1, None], rel_t[:, 1, None])
    return feats[:, 0, ..., :3], b_in_a[..., :3]


def pair_pjd(feats, rel_R, rel_t, cfg):
    """PJD dynamics of a (B, 2, N + 1, J, 9) two-character clip -> (B, N, C)."""
    pa, pb = common_positions(feats, rel_R, rel_t)
    return pjd_dynamics(pa, pb, cfg.model.pjd_joints, cfg.model.pjd_scale)


def pae_disc_logits(nets, pae_params, disc_params, pjd):
    pae = nnx.merge(nets.pae, pae_params)
    h, prm = pae.encode(pjd)
    logit, _ = nnx.merge(nets.disc, disc_params)(h, prm)
    return logit


def ar_predict(nets, gen_params, batch, key, cfg, forward_axis, p_pred):
    """Training autoregression: P steps with scheduled sampling (per-sample Bernoulli(p_pred) choice of the
    prediction over the ground truth as the next input).  Returns preds / coarse (B, 2, P*l, J, 9), mu, logvar
    (P, B, 2, J, Z)."""
    d, P = cfg.data, cfg.train.ar_steps
    T, l = d.n_input, d.n_pred
    x = batch["x"]
    B = x.shape[0]
    gt = jnp.moveaxis(x[:, :, T:T + P * l].reshape(x.shape[:2] + (P, l) + x.shape[3:]), 2, 0)

    def step(win, inp):
        g, k = inp
        k1, k2 = jax.random.split(k)
        out = generator_step(nets.gen, gen_params, win, batch["keypose"], batch["rel_R"], batch["rel_t"], k1,
                             cfg, forward_axis)
        use = jax.random.bernoulli(k2, p_pred, (B, 1, 1, 1, 1))
        nxt = jnp.where(use, out["pred"], g)
        return jnp.concatenate([win[:, :, l:], nxt], axis=2), out

    _, outs = jax.lax.scan(step, x[:, :, :T], (gt, jax.random.split(key, P)))
    cat = lambda a: jnp.moveaxis(a, 0, 2).reshape((B, 2, P * l) + a.shape[4:])  # noqa: E731
    return cat(outs["pred"]), cat(outs["coarse"]), outs["mu"], outs["logvar"]


def make_training(cfg, num_joints: int, forward_axis, train_pairs=None):
    """-> (nets, init_fn, train_step_fn, batch_fn) for :func:`run_training` (batch_fn needs ``train_pairs``)."""
    nets, _ = init_params(jax.random.key(0), num_joints, cfg)
    tx = make_optimizer(cfg)
    d, m, t = cfg.data, cfg.model, cfg.train
    T, N = d.n_input, t.ar_steps * d.n_pred
    if m.gan and m.pjd_frames != N:
        raise ValueError(f"model.pjd_frames ({m.pjd_frames}) must equal ar_steps * n_pred ({N})")
    fa = np.asarray(forward_axis, np.float32)

    def init_fn(key):
        _, params = init_params(key, num_joints, cfg)
        return {"params": params, "opt": tx.init(params), "step": jnp.zeros((), jnp.int32)}

    def losses(params, batch, key):
        sg = jax.lax.stop_gradient
        p_pred = t.ss_max * jnp.minimum(1.0, batch["step"] / max(t.ss_ramp_steps, 1))
        pred, coarse, mu, logvar = ar_predict(nets, params["gen"], batch, key, cfg, fa, p_pred)
        gt = batch["x"][:, :, T:T + N]
        mse = jnp.mean((pred - gt) ** 2)
        coarse_mse = jnp.mean((coarse - gt) ** 2)
        kl = kl_divergence(mu, logvar) if m.interaction else jnp.zeros(())
        total = t.w_mse * mse + t.w_coarse * coarse_mse + t.w_kl * kl
        refined = refine(nets.ref, params["ref"], sg(pred).reshape(pred.shape[:2] + (t.ar_steps, d.n_pred)
                                                                   + pred.shape[3:]).swapaxes(1, 2)
                         .reshape((-1, 2, d.n_pred) + pred.shape[3:]))
        gt_seg = gt.reshape(gt.shape[:2] + (t.ar_steps, d.n_pred) + gt.shape[3:]).swapaxes(1, 2)
        ref_loss = jnp.mean((refined - gt_seg.reshape(refined.shape)) ** 2)
        total = total + t.w_refine * ref_loss
        metrics = dict(mse=mse, coarse_mse=coarse_mse, kl=kl, refine=ref_loss, p_pred=p_pred)
        aux = {}
        if m.gan:
            prev = batch["x"][:, :, T - 1:T]
            pjd_real = pair_pjd(batch["x"][:, :, T - 1:T + N], batch["rel_R"], batch["rel_t"], cfg)
            pjd_fake = pair_pjd(jnp.concatenate([prev, pred], 2), batch["rel_R"], batch["rel_t"], cfg)
            logit_f = pae_disc_logits(nets, sg(params["pae"]), sg(params["disc"]), pjd_fake)
            adv = jnp.mean(jax.nn.softplus(-logit_f))
            recon, _, _ = nnx.merge(nets.pae, params["pae"])(pjd_real)
            pae_loss = jnp.mean((recon - pjd_real) ** 2)
            total = total + t.w_adv * adv + t.w_pae * pae_loss
            metrics.update(adv=adv, pae=pae_loss)
            aux = dict(pjd_real=pjd_real, pjd_fake=sg(pjd_fake))
        metrics["loss"] = total
        return total, (metrics, aux)

    def train_step_fn(state, batch, key):
        params = state["params"]
        batch = dict(batch, step=state["step"].astype(jnp.float32))
        grads, (metrics, aux) = jax.grad(losses, has_aux=True)(params, batch, key)
        if m.gan:
            def d_loss(disc_params):
                pae = jax.lax.stop_gradient(params["pae"])
                lr_ = pae_disc_logits(nets, pae, disc_params, aux["pjd_real"])
                lf = pae_disc_logits(nets, pae, disc_params, aux["pjd_fake"])
                return jnp.mean(jax.nn.softplus(-lr_)) + jnp.mean(jax.nn.softplus(lf))
            dl, gd = jax.value_and_grad(d_loss)(params["disc"])
            grads = dict(grads, disc=gd)
            metrics["disc"] = dl
        updates, opt = tx.update(grads, state["opt"], params)
        params = optax.apply_updates(params, updates)
        return {"params": params, "opt": opt, "step": state["step"] + 1}, metrics

    def batch_fn(step, key):
        rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).astype(np.uint32))
        b = sample_batch(train_pairs, rng, t.batch_size, T + N, (d.key_min, d.key_max), d.mirror, d.pos_scale)
        return {k: b[k] for k in BATCH_KEYS}

    return nets, init_fn, train_step_fn, batch_fn
