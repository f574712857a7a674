"""The CAE's loss (Sec. 3.3): the L1 reconstruction error over the whole clip (optionally with the missing
entries weighted more, ``loss.gap_weight``; not the paper), and the gap-only L1 it logs.

"Please note that we compute the loss over the entire motion sequence, not just the masked portion."
"""
from __future__ import annotations

import jax.numpy as jnp

__all__ = ["l1_loss", "weighted_l1", "masked_l1"]


def l1_loss(pred, target):
    """``mean |pred - target|`` over every entry: pred, target [B, D, T] -> scalar (the training loss)."""
    return jnp.mean(jnp.abs(pred - target))


def weighted_l1(pred, target, mask, gap_weight: float = 1.0):
    """L1 with the missing entries weighted ``gap_weight`` times: ``sum(W |pred - target|) / sum(W)`` with
    ``W = 1 + (gap_weight - 1) (1 - mask)``; equals :func:`l1_loss` at ``gap_weight = 1``.
    pred, target, mask [B, D, T] (mask 1 = known) -> scalar."""
    if float(gap_weight) == 1.0:
        return l1_loss(pred, target)
    w = 1.0 + (float(gap_weight) - 1.0) * (1.0 - mask)
    return jnp.sum(w * jnp.abs(pred - target)) / jnp.sum(w)


def masked_l1(pred, target, mask):
    """Mean ``|pred - target|`` over the missing entries only (``mask`` [B, D, T], 1 = known, 0 = missing);
    0 when nothing is missing.  pred, target [B, D, T] -> scalar (logged as ``hole_l1``)."""
    hole = 1.0 - mask
    return jnp.sum(jnp.abs(pred - target) * hole) / jnp.maximum(jnp.sum(hole), 1.0)
