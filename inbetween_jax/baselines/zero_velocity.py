"""Zero-velocity baseline: hold the last past frame for the whole transition."""
from __future__ import annotations

from inbetween_jax.geometry.quaternion import _xp


def zero_velocity_transition(local_quats, root_pos, n_past: int, n_trans: int):
    """Repeat frame ``n_past - 1`` for the ``n_trans`` transition frames.

    local_quats: (B, T, J, 4); root_pos: (B, T, 3) with T >= n_past.
    Returns (trans_quats (B, n_trans, J, 4), trans_root (B, n_trans, 3)).
    """
    xp = _xp(local_quats, root_pos)
    q = local_quats[:, n_past - 1: n_past]
    r = root_pos[:, n_past - 1: n_past]
    return (xp.repeat(q, n_trans, axis=1), xp.repeat(r, n_trans, axis=1))
