"""Loss terms of the interaction in-betweening model (Sec. 4.1.3 and 4.2), pure functions.

Generator: ``L = w_mse MSE + w_coarse MSE_coarse + w_kl KL + w_refine L_refine + w_adv L_adv + w_pae L_pae
+ w_speed L_speed`` (:func:`generator_objective`; ``w_speed`` 0 in every preset, :func:`speed_energy`; ``w_adv``
optionally warmed up late, :func:`adversarial_weight`); the refiner learns ``Refiner(pred) -> ground truth`` on the
stop-gradient predictions, the periodic autoencoder reconstructs real pairwise-joint-distance (PJD) dynamics and the
discriminator (:func:`discriminator_loss`) separates PAE latents of real and generated N = P * l frame PJD
dynamics.  The parameter groups are disjoint and each only receives gradients of its own term.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from inbetween_jax.models.interaction.features import to_common_space
from inbetween_jax.models.interaction.layers import pjd_dynamics
from inbetween_jax.models.interaction.model import ar_predict, disc_logits, pae_reconstruct, refine

__all__ = ["mse", "kl_divergence", "generator_adversarial", "discriminator_loss", "segments", "pair_pjd",
           "scheduled_sampling_prob", "adversarial_weight", "speed_energy", "generator_objective",
           "discriminator_objective"]


def mse(pred, target, w_pos: float = 1.0):
    """Mean squared error over all elements: [B, 2, N, J, 9] x2 -> scalar.  ``w_pos`` weighs the position
    channels (the first 3 of 9, metres) ``w_pos`` times; 1 is the paper's plain MSE."""
    err = (pred - target) ** 2
    if float(w_pos) == 1.0:
        return jnp.mean(err)
    w = jnp.concatenate([jnp.full((3,), float(w_pos)), jnp.ones((err.shape[-1] - 3,))]).astype(err.dtype)
    return jnp.mean(err * w)


def kl_divergence(mu, logvar):
    """Mean of ``-0.5 (1 + logvar - mu^2 - exp(logvar))`` (Eq. 6) over all elements: [P, B, 2, J, Z] -> scalar."""
    return jnp.mean(-0.5 * (1.0 + logvar - mu ** 2 - jnp.exp(logvar)))


def generator_adversarial(logit_fake):
    """Non-saturating generator loss ``mean softplus(-D(fake))``: [B] -> scalar."""
    return jnp.mean(jax.nn.softplus(-logit_fake))


def discriminator_loss(logit_real, logit_fake):
    """``mean softplus(-D(real)) + mean softplus(D(fake))``: [B] x2 -> scalar."""
    return jnp.mean(jax.nn.softplus(-logit_real)) + jnp.mean(jax.nn.softplus(logit_fake))


def segments(x, P: int, l: int):
    """[B, 2, P*l, J, 9] -> [B*P, 2, l, J, 9]: the l-frame segments the refiner works on."""
    return x.reshape(x.shape[:2] + (P, l) + x.shape[3:]).swapaxes(1, 2).reshape((-1, 2, l) + x.shape[3:])


def speed_energy(pred, gt, prev):
    """Phase-free motion-energy loss: per character and joint, the mean joint speed over the predicted frames of
    ``pred`` against that of ``gt``, squared relative to the batch's mean ground-truth speed (so 0.16 means the
    speeds are off by about 40 %).  It does not ask for the right frame of a step, only for as much motion as the
    capture has; a regression to the mean of uncertain steps loses it.  pred, gt [B, 2, N, J, 9], prev
    [B, 2, 1, J, 9] (the last input frame) -> scalar."""
    def mean_speed(x):
        pos = jnp.concatenate([prev, x], 2)[..., :3]
        step = pos[:, :, 1:] - pos[:, :, :-1]
        return jnp.sqrt(jnp.sum(step ** 2, -1) + 1e-10).mean(2)     # [B, 2, J]; finite gradient on held frames
    s_gt = mean_speed(gt)
    return jnp.mean(((mean_speed(pred) - s_gt) / (jnp.mean(s_gt) + 1e-6)) ** 2)


def pair_pjd(feats, rel_R, rel_t, cfg):
    """PJD dynamics (Eq. 8-9) of a [B, 2, N + 1, J, 9] two-character clip in key spaces -> [B, N, C]."""
    common = to_common_space(feats, rel_R, rel_t)
    return pjd_dynamics(common[:, 0, ..., :3], common[:, 1, ..., :3], cfg.model.pjd_joints, cfg.model.pjd_scale)


def scheduled_sampling_prob(step, cfg):
    """P(feed the prediction back) at ``step``: ``ss_max * min(1, step / ss_ramp_steps)``."""
    d = cfg.data
    return d.ss_max * jnp.minimum(1.0, step / max(d.ss_ramp_steps, 1))


def adversarial_weight(step, cfg):
    """``w_adv`` at ``step``: 0 before ``adv_start``, then a linear ramp over ``adv_ramp`` steps (at once if 0)."""
    w = cfg.loss
    if w.adv_ramp > 0:
        return w.w_adv * jnp.clip((step - w.adv_start) / w.adv_ramp, 0.0, 1.0)
    return w.w_adv * (step >= w.adv_start).astype(jnp.float32)


def generator_objective(params, batch, key, cfg, forward_axis):
    """Total generator / refiner / PAE loss of a batch.

    params: ``{gen, ref, pae, disc}``; batch: ``x`` [B, 2, T + P*l, J, 9], ``keypose`` [B, 2, J, 9],
    ``rel_R`` [B, 2, 3, 3], ``rel_t`` [B, 2, 3], ``step`` (float scalar), ``tta`` [B] (timed models).  Returns ``(total, (metrics, aux))``
    with ``aux = {pjd_real, pjd_fake}`` ([B, N, C], for the discriminator; empty without the GAN).
    """
    sg = jax.lax.stop_gradient
    d, m, w = cfg.data, cfg.model, cfg.loss
    T, P, l = d.n_input, d.ar_steps, d.n_pred
    N = P * l
    J = batch["x"].shape[3]
    p_pred = scheduled_sampling_prob(batch["step"], cfg)
    pred, coarse, mu, logvar = ar_predict(params["gen"], batch, key, cfg, forward_axis, p_pred)
    gt = batch["x"][:, :, T:T + N]
    mse_ = mse(pred, gt, w.w_pos)
    coarse_mse = mse(coarse, gt, w.w_pos)
    kl = kl_divergence(mu, logvar) if m.interaction else jnp.zeros(())
    total = w.w_mse * mse_ + w.w_coarse * coarse_mse + w.w_kl * kl
    refined = refine(params["ref"], segments(sg(pred), P, l), cfg)
    ref_loss = mse(refined, segments(gt, P, l), w.w_pos)
    total = total + w.w_refine * ref_loss
    metrics = dict(mse=mse_, coarse_mse=coarse_mse, kl=kl, refine=ref_loss, p_pred=p_pred)
    prev = batch["x"][:, :, T - 1:T]                                   # the last input frame
    if w.w_speed > 0:
        speed = speed_energy(pred, gt, prev)
        total = total + w.w_speed * speed
        metrics["speed"] = speed
    aux = {}
    if m.gan:
        pjd_real = pair_pjd(batch["x"][:, :, T - 1:T + N], batch["rel_R"], batch["rel_t"], cfg)
        pjd_fake = pair_pjd(jnp.concatenate([prev, pred], 2), batch["rel_R"], batch["rel_t"], cfg)
        adv = generator_adversarial(disc_logits(sg(params["pae"]), sg(params["disc"]), pjd_fake, cfg, J))
        recon, _, _ = pae_reconstruct(params["pae"], pjd_real, cfg, J)
        pae_loss = mse(recon, pjd_real)
        if w.adv_start > 0 or w.adv_ramp > 0:
            w_adv = adversarial_weight(batch["step"], cfg)
            metrics["w_adv"] = w_adv
        else:
            w_adv = w.w_adv
        total = total + w_adv * adv + w.w_pae * pae_loss
        metrics.update(adv=adv, pae=pae_loss)
        aux = dict(pjd_real=pjd_real, pjd_fake=sg(pjd_fake))
    metrics["loss"] = total
    return total, (metrics, aux)


def discriminator_objective(disc_params, pae_params, pjd_real, pjd_fake, cfg, num_joints: int):
    """Discriminator loss on real / generated PJD dynamics [B, N, C] (the PAE is held fixed): scalar."""
    pae = jax.lax.stop_gradient(pae_params)
    return discriminator_loss(disc_logits(pae, disc_params, pjd_real, cfg, num_joints),
                              disc_logits(pae, disc_params, pjd_fake, cfg, num_joints))
