"""Deferred weight gradients: a training-only speed-up of the S-CVAE step (``model.deferred_wgrad``).

Autodiff through the rollout's ``lax.scan`` forms the weight gradient of every per-step matmul as one small
matmul plus a full-size accumulating add per step.  For the largest matmuls (the encoder LSTM, the packed
decoder LSTM and the first packed expert layer of each generator) the step instead

1. passes zero *taps* shaped like the products (:func:`make_taps`) into :func:`model.rollout
   <inbetween_jax.models.scvae.model.rollout>`, where :func:`tapped_matmul` stops the weight gradient and
   adds the tap, so ``d loss / d tap_t`` is the product's cotangent at step t;
2. records the matmul inputs x_t of every step (the rollout returns them as ``rec_fwd`` / ``rec_bwd``);
3. adds ``d loss / d w = sum_t x_t^T (d loss / d tap_t)`` as one large matmul after the scan
   (:func:`add_deferred_weight_grads`).

The gradient is the same (up to float summation order); tests compare it with plain autodiff.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["tapped_matmul", "make_taps", "add_deferred_weight_grads"]


def tapped_matmul(x, w, tap=None):
    """``x @ w``; with a ``tap`` (zeros shaped like the product) the weight gradient is left to the caller.

    ``w`` is wrapped in ``stop_gradient`` and ``tap`` added to the product, so ``d loss / d tap`` is the
    product's cotangent.  Given the recorded inputs x_t of every scan step, the caller forms
    ``d loss / d w = sum_t x_t^T (d loss / d tap_t)`` as one large matmul after the scan instead of one
    small matmul plus a full-size accumulating add per step.  Gradients to ``x`` are unchanged.
    """
    if tap is None:
        return x @ w
    return x @ jax.lax.stop_gradient(w) + tap


def make_taps(params: dict, cfg, batch: int, steps: int) -> dict:
    """Zero taps for :func:`~inbetween_jax.models.scvae.model.rollout` (deferred weight gradients of the encoder
    LSTM, the packed decoder LSTM and the first expert layer of each generator): {generator: {name: (S, rows,
    cols)}} with S = ``steps``, the rollout's scan length (``model.num_scan_steps``).  cfg: ModelConfig."""
    out = {}
    for name, g in params.items():
        four_h = g["dec"]["lstm"]["b"].shape[0]
        e, o = g["dec"]["experts"][0]["b"].shape
        t = {"dec_w": jnp.zeros((steps, batch, four_h)), "moe0": jnp.zeros((steps, batch, e * o))}
        if cfg.encoder_lstm:
            four_he = g["enc"]["lstm"]["b"].shape[0]
            t.update(enc_wh=jnp.zeros((steps, batch, four_he)), enc_wx=jnp.zeros((steps, 2 * batch, four_he)))
        out[name] = t
    return out


def add_deferred_weight_grads(grads: dict, recs: dict, tap_grads: dict) -> dict:
    """Autodiff ``grads`` (zero at the tapped weights) plus the tapped matmuls' weight gradients,
    ``sum_t x_t^T g_t`` as one matmul each, mapped back to the unpacked parameter layout.
    recs: {generator: {name: (S, rows, d_in)}}; tap_grads like :func:`make_taps`.  Only the tapped leaves
    change; returns a new pytree shaped like ``grads``."""
    out = jax.tree.map(lambda x: x, grads)     # new containers, same leaves
    for name, rec in recs.items():
        g = tap_grads[name]
        dw = {k: rec[k].reshape(-1, rec[k].shape[-1]).T @ g[k].reshape(-1, g[k].shape[-1]) for k in rec}
        lstm, expert = out[name]["dec"]["lstm"], out[name]["dec"]["experts"][0]
        d_x = lstm["wx"].shape[0]
        e, i, o = expert["w"].shape
        lstm["wx"], lstm["wh"] = lstm["wx"] + dw["dec_w"][:d_x], lstm["wh"] + dw["dec_w"][d_x:]
        expert["w"] = expert["w"] + jnp.transpose(dw["moe0"].reshape(i, e, o), (1, 0, 2))
        if "enc_wx" in dw:
            enc = out[name]["enc"]["lstm"]
            enc["wx"], enc["wh"] = enc["wx"] + dw["enc_wx"], enc["wh"] + dw["enc_wh"]
    return out
