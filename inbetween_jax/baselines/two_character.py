"""Per-character interpolation for two characters: the independent-characters baseline of the interaction
in-betweening table (each character interpolated on its own, no interaction)."""
from __future__ import annotations

import jax.numpy as jnp

from inbetween_jax.geometry import quat_from_forward_up, quat_slerp, quat_to_forward_up

__all__ = ["two_character_interpolation"]


def two_character_interpolation(last, keypose, length: int):
    """Per-character interpolation: last (B, 2, J, 9) -> keypose (B, 2, J, 9) over ``length`` frames
    (the keypose itself excluded).  Features: position (3) + forward / up of the global rotation (6);
    positions lerp, rotations slerp.  Returns (B, 2, length, J, 9)."""
    last, keypose = jnp.asarray(last), jnp.asarray(keypose)
    t = (jnp.arange(1, length + 1, dtype=jnp.float32) / (length + 1))[:, None]            # (L, 1)
    a, b = last[:, :, None], keypose[:, :, None]                                          # (B, 2, 1, J, 9)
    pos = a[..., :3] + (b[..., :3] - a[..., :3]) * t[..., None]
    qa, qb = quat_from_forward_up(a[..., 3:]), quat_from_forward_up(b[..., 3:])
    shape = pos.shape[:-1]
    q = quat_slerp(jnp.broadcast_to(qa, shape + (4,)), jnp.broadcast_to(qb, shape + (4,)),
                   jnp.broadcast_to(t, shape))
    return jnp.concatenate([pos, quat_to_forward_up(q)], -1)
