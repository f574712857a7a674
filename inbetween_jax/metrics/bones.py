"""Bone-length consistency of predicted joint positions (the CAE benchmark's bone-length table).

A model that predicts joint positions (not rotations) does not keep the skeleton's bone lengths; these
statistics say by how much, per bone over every frame, averaged over the bones.  Pure ``jax.numpy``, jitted
(``parents`` is static: pass a tuple).  Units: the positions' (cm for LaFAN1 / CMU).
"""
from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

__all__ = ["bone_length_spread"]


def _lengths(pos, parents):
    par = jnp.asarray(parents[1:])
    bl = jnp.linalg.norm(pos[..., 1:, :] - pos[..., par, :], axis=-1)      # (..., J-1)
    return bl.reshape(-1, bl.shape[-1])


@functools.partial(jax.jit, static_argnames=("parents",))
def bone_length_spread(pred_pos, gt_pos, parents: tuple) -> dict:
    """Spread of every bone's length over all frames, mean over the J-1 bones.

    pred_pos, gt_pos: (..., J, 3) positions (any leading dims: clips, frames; they need not match);
    parents: the skeleton's parent indices (tuple, root first).  With ``l_b`` bone b's lengths over the
    predicted frames and ``g_b`` over the ground-truth frames, returns scalars::

        median_dev = mean_b |median(l_b) - median(g_b)|      std = mean_b std(l_b)   (population std)
        iqr        = mean_b (P75(l_b) - P25(l_b))             gt_std = mean_b std(g_b)
    """
    pb = _lengths(jnp.asarray(pred_pos), parents)
    gb = _lengths(jnp.asarray(gt_pos), parents)
    q75, q25 = jnp.percentile(pb, jnp.asarray([75.0, 25.0]), axis=0)
    return {"median_dev": jnp.mean(jnp.abs(jnp.median(pb, 0) - jnp.median(gb, 0))),
            "std": jnp.mean(pb.std(0)), "iqr": jnp.mean(q75 - q25), "gt_std": jnp.mean(gb.std(0))}
