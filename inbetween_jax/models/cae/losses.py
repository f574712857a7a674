"""The CAE's loss (Sec. 3.3): the L1 reconstruction error over the whole clip, and the gap-only L1 it logs.

"Please note that we compute the loss over the entire motion sequence, not just the masked portion."
"""
from __future__ import annotations

import jax.numpy as jnp

__all__ = ["l1_loss", "masked_l1"]


def l1_loss(pred, target):
    """``mean |pred - target|`` over every entry: pred, target [B, D, T] -> scalar (the training loss)."""
    return jnp.mean(jnp.abs(pred - target))


def masked_l1(pred, target, mask):
    """Mean ``|pred - target|`` over the missing entries only (``mask`` [B, D, T], 1 = known, 0 = missing);
    0 when nothing is missing.  pred, target [B, D, T] -> scalar (logged as ``hole_l1``)."""
    hole = 1.0 - mask
    return jnp.sum(jnp.abs(pred - target) * hole) / jnp.maximum(jnp.sum(hole), 1.0)
