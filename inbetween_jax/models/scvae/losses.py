"""S-CVAE losses (paper 3.4): state (Eq. 5), KL (Eq. 6), FK (Eq. 7), stitching (Eq. 4), LSGAN (Eq. 8-9)
with long (10-frame) and short (2-frame) discriminators, and the phase network's regression loss.

L1 "norms" are means over elements (``torch.nn.L1Loss`` convention) and then masked means over the valid
frames of the batch.  Root velocities are compared in units of their training std, positions in units of
``stats["pos_unit"]`` (the mean per-coordinate std of the training global positions, i.e. L2P's scale).

``gt`` sequences are dicts in one generator's own time order: q (B, T, J, 4), r (B, T, 3), c (B, T, 4),
phase (B, T, 4); frame 0 is that generator's keyframe.
"""
from __future__ import annotations

import jax.numpy as jnp

from inbetween_jax.geometry import forward_kinematics, local_positions
from inbetween_jax.models.scvae import layers as nn
from inbetween_jax.models.scvae.model import phase_step


def velocity(r):
    """(B, T, 3) -> (B, T, 3) with v_0 = 0."""
    return jnp.concatenate([jnp.zeros_like(r[:, :1]), r[:, 1:] - r[:, :-1]], axis=1)


def fk_positions(q, r, stats, parents):
    """q (..., J, 4), r (..., 3) -> global positions (..., J, 3)."""
    return forward_kinematics(q, local_positions(r, stats["offsets"]), parents)[1]


def masked_mean(x, mask):
    """x (B, S) per-frame values, mask (S,) or (B, S) -> scalar mean over masked entries."""
    mask = jnp.broadcast_to(mask, x.shape).astype(x.dtype)
    return jnp.sum(x * mask) / jnp.maximum(jnp.sum(mask), 1.0)


def direction_losses(pred: dict, pos, kl, valid, gt: dict, stats, lcfg) -> dict:
    """State, KL and FK losses of one generator.  pred: frames (B, S, ...) where step m is own-time frame
    m + 1; pos (B, S, J, 3) their FK positions; kl (B, S, Z) per latent dimension; valid (S,); gt also holds positions p (B, T, J, 3).
    Returns a dict of scalars."""
    s = pred["q"].shape[1]
    g = {k: gt[k][:, 1:s + 1] for k in ("q", "r", "c")}
    g["v"] = velocity(gt["r"])[:, 1:s + 1]
    quat = jnp.mean(jnp.abs(pred["q"] - g["q"]), axis=(-1, -2))
    vel = jnp.mean(jnp.abs(pred["v"] - g["v"]) / stats["v_std"], axis=-1)
    con = jnp.mean(jnp.abs(pred["c"] - g["c"]), axis=-1)
    state = masked_mean(lcfg.beta_quat * quat + lcfg.beta_vel * vel + lcfg.beta_contact * con, valid)
    gpos = gt["p"][:, 1:s + 1]
    fk = masked_mean(jnp.mean(jnp.abs(pos - gpos), axis=(-1, -2)) / stats["pos_unit"], valid)
    return {"state": state, "kl": masked_mean(jnp.sum(kl, -1), valid), "kl_term": masked_mean(kl_term(kl, lcfg), valid),
            "fk": fk}


def kl_term(kl, lcfg):
    """The KL loss term from per-dimension KL (..., Z) in nats.  ``kl_reduce="sum"`` (paper): the sum over
    the Z dimensions; ``"mean"``: their mean.  ``free_bits`` > 0: each dimension's KL below that many nats is
    not penalised (max(KL_d, free_bits), Kingma et al. 2016), so the latent can carry information."""
    if lcfg.free_bits > 0:
        kl = jnp.maximum(kl, lcfg.free_bits)
    return jnp.mean(kl, -1) if lcfg.kl_reduce == "mean" else jnp.sum(kl, -1)


def stitch_loss(pos_f, pos_b, length, h, k, pos_unit=1.0):
    """Eq. 4: mean L1 between forward and backward FK positions over t = h-K+1 .. h+K (forward time).

    pos_f / pos_b: (B, S, J, 3) in generation order (forward step m = time m+1, backward step m = time L-1-m).
    """
    s = pos_f.shape[1]
    t = jnp.arange(1, s + 1)
    bi = jnp.clip(length - 1 - t, 0, s - 1)
    pb = jnp.take(pos_b, bi, axis=1)
    mask = (t >= h - k + 1) & (t <= h + k)
    return masked_mean(jnp.mean(jnp.abs(pos_f - pb), axis=(-1, -2)), mask) / pos_unit


def phase_loss(phase_params, gt: dict, length, stats):
    """Teacher-forced L1 of the phase network on labels: phase_{t+1} = label_t + net(state_t, label_t),
    and the keyframe phase net(state_0 with v = 0, phase 0) against label_0."""
    b, t = gt["q"].shape[:2]
    frames = {"q": gt["q"], "v": velocity(gt["r"]), "c": gt["c"], "phase": gt["phase"]}
    flat = {k: v.reshape((b * t,) + v.shape[2:]) for k, v in frames.items()}
    nxt = phase_step(phase_params, flat, stats).reshape(b, t, -1)
    step_err = jnp.mean(jnp.abs(nxt[:, :-1] - gt["phase"][:, 1:]), -1)
    steps_mask = jnp.arange(t - 1) < length
    first = {"q": gt["q"][:, 0], "v": jnp.zeros_like(gt["r"][:, 0]), "c": gt["c"][:, 0],
             "phase": jnp.zeros_like(gt["phase"][:, 0])}
    init_err = jnp.mean(jnp.abs(phase_step(phase_params, first, stats) - gt["phase"][:, 0]))
    return masked_mean(step_err, steps_mask) + init_err


# ----------------------------------------------------------------------------- discriminators
def disc_features(seq: dict, stats):
    """Per-frame discriminator input (B, T, 4J+7): local quats, normalised root velocity, contacts."""
    b, t = seq["q"].shape[:2]
    return jnp.concatenate([seq["q"].reshape(b, t, -1), velocity(seq["r"]) / stats["v_std"], seq["c"]], -1)


def init_discriminators(key, cfg, feat_dim: int) -> dict:
    """Long / short discriminators: (window * D) -> 512 -> 256 -> 1."""
    f = nn.ParamFactory()
    hid = tuple(cfg.disc_hidden)
    return f.materialize({"long": nn.init_mlp(f, (cfg.disc_long * feat_dim,) + hid + (1,)),
                          "short": nn.init_mlp(f, (cfg.disc_short * feat_dim,) + hid + (1,))}, key)


def disc_scores(params: list, feats, window: int, length):
    """Scores of every sliding window of ``window`` frames inside frames 0..length.

    feats (B, T, D) -> (scores (B, W), mask (W,)) with W = T - window + 1."""
    t = feats.shape[1]
    n = t - window + 1
    win = jnp.concatenate([feats[:, i:i + n] for i in range(window)], axis=-1)  # (B, n, window*D)
    mask = jnp.arange(n) + window - 1 <= length
    return nn.mlp(params, win)[..., 0], mask


def lsgan_losses(dparams: dict, cfg, fake_feats, real_feats, length):
    """Eq. 8-9 summed over the long and short discriminators: returns (L_G, L_D)."""
    lg = ld = 0.0
    for name, w in (("long", cfg.disc_long), ("short", cfg.disc_short)):
        f, mask = disc_scores(dparams[name], fake_feats, w, length)
        r, _ = disc_scores(dparams[name], real_feats, w, length)
        lg = lg + 0.5 * masked_mean((f - 1.0) ** 2, mask)
        ld = ld + 0.5 * masked_mean((r - 1.0) ** 2, mask) + 0.5 * masked_mean(f ** 2, mask)
    return lg, ld
