"""NPSS, Normalized Power Spectrum Similarity (Gopalakrishnan et al. 2019), LaFAN1 ``fast_npss``."""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["npss", "fast_npss"]


@jax.jit
def npss(gt_seq, pred_seq):
    """NPSS as in ``lafan1/benchmarks.py::fast_npss`` (note the argument order: ground truth first).

    With x of shape (B, T, D) (D = J*4 flattened global quaternions in the benchmark):

        F_x[b, k, d]   = Re( sum_t x[b, t, d] exp(-2 pi i k t / T) )     (REAL part of the FFT)
        P_x            = F_x ** 2
        S_x[b, d]      = sum_k P_x[b, k, d]
        C_x[b, k, d]   = sum_{k' <= k} P_x[b, k', d] / S_x[b, d]         (normalised power CDF)
        emd[b, d]      = sum_k | C_pred[b, k, d] - C_gt[b, k, d] |
        NPSS           = sum_{b,d} S_gt[b, d] emd[b, d] / sum_{b,d} S_gt[b, d]

    Zero-power guard (the official code returns NaN / raises there): a channel whose total power is
    0 gets a zero normalised CDF instead of 0/0; such a ground-truth channel also has weight 0, so
    it does not count. If every ground-truth channel has zero power the result is 0.0.
    Where all totals are positive the result equals the official one.

    gt_seq, pred_seq: (B, T, D), or (B, T, ...) which is flattened to (B, T, D) like the official
    ``flatjoints``. Returns a scalar, unitless (>= 0; 0 for identical spectra).
    """
    gt_seq = jnp.asarray(gt_seq)
    pred_seq = jnp.asarray(pred_seq)
    if gt_seq.ndim < 3:
        raise ValueError(f"NPSS expects (B, T, D) inputs, got shape {gt_seq.shape}")
    gt_seq = gt_seq.reshape(gt_seq.shape[0], gt_seq.shape[1], -1)
    pred_seq = pred_seq.reshape(pred_seq.shape[0], pred_seq.shape[1], -1)
    dtype = jnp.result_type(gt_seq.dtype, pred_seq.dtype, jnp.float32)

    def power(x):
        return jnp.real(jnp.fft.fft(x.astype(dtype), axis=1)) ** 2

    gt_power = power(gt_seq)
    pred_power = power(pred_seq)
    gt_total = jnp.sum(gt_power, axis=1)  # (B, D)
    pred_total = jnp.sum(pred_power, axis=1)

    def cdf(p, total):
        safe = jnp.where(total > 0, total, 1.0)
        normed = jnp.where(total[:, None, :] > 0, p / safe[:, None, :], 0.0)
        return jnp.cumsum(normed, axis=1)

    emd = jnp.sum(jnp.abs(cdf(pred_power, pred_total) - cdf(gt_power, gt_total)), axis=1)  # (B, D)
    weight_sum = jnp.sum(gt_total)
    safe_sum = jnp.where(weight_sum > 0, weight_sum, 1.0)
    return jnp.where(weight_sum > 0, jnp.sum(emd * gt_total) / safe_sum, 0.0)


fast_npss = npss
