"""Orthonormal DCT-II / DCT-III (inverse) along the time axis, as a matrix product (jit friendly)."""
from __future__ import annotations

import numpy as np
import jax.numpy as jnp


def dct_matrix(n: int) -> np.ndarray:
    """Orthonormal DCT-II basis ``D`` (n, n): ``coeffs = D @ x`` and ``x = D.T @ coeffs``."""
    if n < 1:
        raise ValueError(f"DCT length must be >= 1, got {n}")
    k = np.arange(n)[:, None]
    t = np.arange(n)[None, :]
    d = np.cos(np.pi * (2 * t + 1) * k / (2 * n)) * np.sqrt(2.0 / n)
    d[0] /= np.sqrt(2.0)
    return d.astype(np.float32)


def dct(x, axis: int = -2, num_coeffs: int | None = None):
    """DCT-II of ``x`` along ``axis`` (default the time axis of (..., T, C)); keeps ``num_coeffs``."""
    x = jnp.moveaxis(x, axis, -1)
    d = jnp.asarray(dct_matrix(x.shape[-1]))
    if num_coeffs is not None:
        d = d[:num_coeffs]
    return jnp.moveaxis(x @ d.T, -1, axis)


def idct(c, n: int | None = None, axis: int = -2):
    """Inverse of :func:`dct`: coefficients (..., K, C) -> signal (..., n, C) (K <= n, zero-padded)."""
    c = jnp.moveaxis(c, axis, -1)
    n = c.shape[-1] if n is None else n
    d = jnp.asarray(dct_matrix(n))[: c.shape[-1]]
    return jnp.moveaxis(c @ d, -1, axis)
