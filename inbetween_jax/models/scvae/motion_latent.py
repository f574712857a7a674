"""A per-transition motion latent for the S-CVAE (``model.motion_latent`` > 0; not in the paper).

Why.  The paper's latent z_t is drawn at every step from an encoder that sees the frame just generated and the
target.  Training rolls the generators out on their own frames, so that encoder never sees the true in-between:
z_t can carry nothing the decoder does not already have, the reconstruction losses teach the decoder to ignore
it, and ten samples come out the same (KL ~1e-5 nats in the improved preset, docs/results/scvae.md).

What.  One latent ``m`` (B, M) per transition, in the usual conditional-VAE shape:

* a **posterior** q(m | keyframes, true in-between) sees every ground-truth frame of the gap as its offset from
  the residual decoder's base path (Slerp / lerp), with its time in the gap, pooled over the gap;
* a **learned conditional prior** p(m | keyframes) sees only the keyframes and the gap length;
* both generators' decoders get ``m`` beside z_t at every step (:func:`..model.generator_step`).

Training draws ``m`` from the posterior and adds KL(q || p) with free bits per dimension
(``loss.motion_free_bits``: nats the posterior may use at no cost, so the latent carries motion) and a term
that always fits the prior to the (stopped) posterior; ``loss.prior_path`` also rolls every window out from the
prior's mean, so the zero-temperature fill stays accurate.  Sampling draws ``m`` from the prior, one per sample,
shared by a sample's latent-pair-search candidates (:func:`spread_draws`): ``model.motion_temperature`` scales the
prior's spread, ``model.motion_spread`` > 1 picks the N draws far apart (farthest-point over that many times N
prior draws, in the prior's whitened space).  Measured in docs/results/scvae.md, "Samples that differ".
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from inbetween_jax.models.scvae import layers as nn
from inbetween_jax.geometry.quaternion import quat_align
from inbetween_jax.models.scvae.features import dims

__all__ = ["init_motion_nets", "time_features", "posterior", "prior", "gaussian_kl", "motion_kl_terms",
           "draw", "spread_draws", "prior_draws"]

NUM_TIME_FREQS = 4


def init_motion_nets(f: nn.ParamFactory, cfg, num_joints: int) -> dict:
    """Posterior (per-frame MLP, masked mean, head) and prior (MLP) parameters.  cfg: ModelConfig."""
    d = dims(num_joints)
    hid, m = cfg.motion_hidden, cfg.motion_latent
    frame_in = 4 * num_joints + 3 + 4 + 2 * NUM_TIME_FREQS
    key_in = 2 * d["target"] + 3 + 4 + 2 * NUM_TIME_FREQS
    return {"post_frame": nn.init_mlp(f, (frame_in, hid, hid)),
            "post_head": nn.init_mlp(f, (hid, hid, 2 * m)),
            "prior": nn.init_mlp(f, (key_in, hid, hid, 2 * m))}


def time_features(t, length):
    """sin / cos of k pi t / L for k = 1..NUM_TIME_FREQS: (..., 2 NUM_TIME_FREQS).  t, length broadcastable."""
    x = jnp.asarray(t, jnp.float32) / jnp.maximum(jnp.asarray(length, jnp.float32), 1.0)
    k = jnp.arange(1, NUM_TIME_FREQS + 1, dtype=jnp.float32)
    a = jnp.pi * x[..., None] * k
    return jnp.concatenate([jnp.sin(a), jnp.cos(a)], -1)


def _gaussian(head_out):
    mu, lv = jnp.split(head_out, 2, -1)
    return mu, jnp.clip(lv, -8.0, 4.0)


def posterior(p: dict, stats: dict, gt: dict, base_q, base_r, length):
    """q(m | keyframes, in-between): (mu, log-variance), each (B, M).

    gt: ``q`` (B, T1, J, 4), ``r`` (B, T1, 3), ``c`` (B, T1, 4) at times 0..max_length (times >= L hold the
    target); base_q / base_r: the residual base path at the same times.  Frames 1..L-1 are pooled."""
    b, t1, j = gt["q"].shape[:3]
    t = jnp.arange(t1)
    dq = (gt["q"] - quat_align(base_q, gt["q"])).reshape(b, t1, 4 * j)
    dr = (gt["r"] - base_r) / stats["off_std"]
    tf = jnp.broadcast_to(time_features(t, length), (b, t1, 2 * NUM_TIME_FREQS))
    h = nn.mlp(p["post_frame"], jnp.concatenate([dq, dr, gt["c"], tf], -1), final_act=True)     # (B, T1, H)
    mask = ((t >= 1) & (t < length)).astype(h.dtype)[None, :, None]
    pooled = jnp.sum(h * mask, 1) / jnp.maximum(jnp.sum(mask), 1.0)
    return _gaussian(nn.mlp(p["post_head"], pooled))


def prior(p: dict, stats: dict, start: dict, target: dict, length, tta_max: int):
    """p(m | keyframes): (mu, log-variance), each (B, M), from both keyframes' local quaternions, the root's
    offset between them, the start's contacts and the gap length."""
    b = start["q"].shape[0]
    tq = quat_align(target["q"], start["q"])
    off = (target["r"] - start["r"]) / stats["off_std"]
    lf = jnp.broadcast_to(time_features(length, tta_max), (b, 2 * NUM_TIME_FREQS))
    x = jnp.concatenate([start["q"].reshape(b, -1), tq.reshape(b, -1), off, start["c"], lf], -1)
    return _gaussian(nn.mlp(p["prior"], x))


def gaussian_kl(mu_q, lv_q, mu_p, lv_p):
    """KL(N(mu_q, e^lv_q) || N(mu_p, e^lv_p)) per dimension (nats), elementwise."""
    return 0.5 * (lv_p - lv_q + (jnp.exp(lv_q) + (mu_q - mu_p) ** 2) * jnp.exp(-lv_p) - 1.0)


def motion_kl_terms(q, prior_params, free_bits: float):
    """(loss term, KL in nats summed over dimensions), both batch means.

    q, prior_params: (mu, log-variance) pairs (B, M).  The term is mean_d max(KL_d, free_bits) (the posterior
    may carry ``free_bits`` nats per dimension at no cost) plus mean_d KL(stop_gradient(q) || p), which keeps
    fitting the prior where the first term is flat."""
    kl = gaussian_kl(*q, *prior_params)                                          # (B, M)
    fit = gaussian_kl(*jax.tree.map(jax.lax.stop_gradient, q), *prior_params)
    term = jnp.mean(jnp.maximum(jnp.mean(kl, 0), free_bits)) + jnp.mean(fit)
    return term, jnp.mean(jnp.sum(kl, -1))


def draw(mu, lv, key):
    """One reparameterised draw (B, M)."""
    return mu + jnp.exp(0.5 * lv) * jax.random.normal(key, mu.shape, mu.dtype)


def spread_draws(mu, lv, keys, spread: int, temperature: float = 1.0):
    """N prior draws (N, B, M), one per key; with ``spread`` > 1 each is the farthest (in the prior's whitened
    space) of ``spread`` x N candidates from those already picked (greedy farthest-point, the first candidate
    first), so few samples still cover the prior.  ``temperature`` scales the prior's standard deviation
    (1: the prior; 0: every draw is its mean).  mu, lv: (B, M); keys: (N,) PRNG keys."""
    n = keys.shape[0]
    lv = lv + 2.0 * jnp.log(jnp.maximum(temperature, 1e-12))
    if spread <= 1:
        return jax.vmap(lambda k: draw(mu, lv, k))(keys)
    eps = jax.random.normal(keys[0], (spread * n,) + mu.shape, mu.dtype)       # (C, B, M) whitened candidates
    first = eps[0]
    dmin = jnp.sum((eps - first) ** 2, -1)                                      # (C, B)

    def pick(dmin, _):
        idx = jnp.argmax(dmin, 0)                                               # (B,)
        chosen = jnp.take_along_axis(eps, idx[None, :, None], 0)[0]             # (B, M)
        return jnp.minimum(dmin, jnp.sum((eps - chosen) ** 2, -1)), chosen

    _, rest = jax.lax.scan(pick, dmin, None, length=n - 1)
    picked = jnp.concatenate([first[None], rest], 0)                            # (N, B, M)
    return mu + jnp.exp(0.5 * lv) * picked


def prior_draws(p: dict, cfg, stats: dict, start: dict, target: dict, length, keys):
    """The N motion latents (N, B, M) a sampler uses, one per key: :func:`spread_draws` of the learned
    :func:`prior` with ``cfg.motion_spread`` and ``cfg.motion_temperature`` (cfg: ModelConfig)."""
    mu, lv = prior(p, stats, start, target, length, cfg.tta_max)
    return spread_draws(mu, lv, keys, cfg.motion_spread, cfg.motion_temperature)
