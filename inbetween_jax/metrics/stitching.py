"""Stitching metric: MMPE, Mean Middle Pose Error between forward and backward generators."""
from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

__all__ = ["mmpe"]


@functools.partial(jax.jit, static_argnames=('mid_index',))
def mmpe(forward_pos, backward_pos, mid_index: int | None = None, scale: float = 1.0):
    """MMPE: how well a forward generator (from the start keyframe) and a backward generator (from
    the end keyframe) meet in the middle of a gap of length L:

        MMPE = scale * mean_{b, j} || p_f[b, m, j] - p_b[b, m, j] ||_2,   m = L // 2 (default)

    forward_pos, backward_pos: (..., L, J, 3) global positions over the same L gap frames, both in
    forward time order (reverse the backward generator's output first if it runs backwards).
    mid_index: the middle frame index m; ``None`` -> L // 2.
    Returns a scalar in input units times ``scale`` (cm for LaFAN1 / CMU data).
    """
    forward_pos = jnp.asarray(forward_pos)
    backward_pos = jnp.asarray(backward_pos)
    m = forward_pos.shape[-3] // 2 if mid_index is None else mid_index
    diff = forward_pos[..., m, :, :] - backward_pos[..., m, :, :]
    return scale * jnp.mean(jnp.sqrt(jnp.sum(diff ** 2, axis=-1)))
