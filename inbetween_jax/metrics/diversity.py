"""Diversity: APD, average pairwise distance between N generated samples (S-CVAE / DLow)."""
from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["apd"]


@jax.jit
def apd(samples, scale: float = 1.0):
    """APD over N samples of the same conditioning (DLow, Yuan & Kitani 2020; S-CVAE):

        APD_b = 1 / (N (N - 1)) * sum_i sum_{j != i} || x_i[b] - x_j[b] ||_2
        APD   = scale * mean_b APD_b

    where x_i[b] is sample i of batch item b flattened to one T*J*C vector (the whole motion).

    samples: (N, B, T, J, C) (typically C = 3 global positions), or (N, B, ...) in general.
    Returns a scalar in input units times ``scale`` (positions in cm: ``scale=0.01`` gives metres).
    N < 2 gives 0.0.
    """
    samples = jnp.asarray(samples)
    num = samples.shape[0]
    if num < 2:
        return jnp.zeros((), jnp.result_type(samples.dtype, jnp.float32))
    flat = samples.reshape(num, samples.shape[1], -1)  # (N, B, F)
    diff = flat[:, None] - flat[None, :]  # (N, N, B, F)
    sq = jnp.sum(diff ** 2, axis=-1)  # (N, N, B), zero on the diagonal
    dist = jnp.sqrt(jnp.where(sq > 0, sq, 0.0))
    per_item = jnp.sum(dist, axis=(0, 1)) / (num * (num - 1))  # (B,)
    return scale * jnp.mean(per_item)
