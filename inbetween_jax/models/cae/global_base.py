"""The CAE's base in global positions where the body stays near its place (``model.global_base_near`` /
``model.global_base_far``, inside a file).

The gate's base (:func:`.gate.base_fill`) interpolates the joints in the body frame: positions relative to the root
on its floor path, turned with the facing across the gap.  That follows a body that walks and turns.  Where the
body stays near its place, the body frame only adds the facing's and the root path's own errors to the limbs', and
where the body is not upright (a fall, floor work) the facing itself is ill-defined: a body-frame fill of a roll
swings the limbs around a facing that turns with it (docs/results/gate.md, "global base").  There the straight
choice is the limited cubic Hermite of each joint's global position, per axis
(:func:`inbetween_jax.baselines.hermite_fill`, limiter 3, edge fade ``model.global_base_fade``).  Per gap
``[a, b)``::

    travel = speed_beside(ref, a, b) * (b - a)                the root's floor speed beside the gap x its frames
    share  = clip((far - travel) / (far - near), 0, 1)        near / far in metres (model.global_base_near / _far)
    base   = body + share * (global - body)                   global joint positions in the gap

:func:`apply` gives the gated fill that part of the gap the gate and the motion match leave to the base:
``pos += (1 - gate_weight) (1 - match_weight) share (global - body)``; where the gate keeps the network, nothing
changes.  Only whole missing frames (gaps) change; joint dropout keeps its fill.
"""
from __future__ import annotations

import numpy as np

__all__ = ["enabled", "travel_share", "global_fill", "base_positions", "apply"]


def enabled(model_cfg) -> bool:
    """Whether a run's ``cfg.model`` asks for the global base (``global_base_far`` > 0)."""
    return float(getattr(model_cfg, "global_base_far", 0.0)) > 0.0


def travel_share(ref, a: int, b: int, near_m: float, far_m: float) -> float:
    """The global fill's share of gap ``[a, b)``'s base: 1 where the root is expected to travel at most ``near_m``
    metres across the gap (its floor speed beside the gap, :func:`.bank.speed_beside`, times the gap's frames; ref
    (T, 2) the root track in cm, known frames only are read), 0 from ``far_m``, linear between."""
    from inbetween_jax.models.cae.bank import speed_beside
    travel = speed_beside(ref, a, b) * (b - a) / 100.0
    return float(np.clip((far_m - travel) / max(far_m - near_m, 1e-9), 0.0, 1.0))


def global_fill(global_pos, frame_mask, edge_fade: float) -> np.ndarray:
    """(T, J, 3) the limited cubic Hermite (edge fade ``edge_fade``) of every joint's global position (T, J, 3)
    across the frames where ``frame_mask`` (T,) is 0; only frames where it is 1 are read."""
    from inbetween_jax.baselines import hermite_fill
    gp = np.asarray(global_pos, np.float32)
    t, j, _ = gp.shape
    known = np.asarray(frame_mask).reshape(-1) > 0.5
    rows = np.where(known[:, None, None], gp, 0.0).reshape(t, j * 3).T                  # (3J, T)
    filled = hermite_fill(rows, known[None].astype(np.float32), edge_fade=float(edge_fade))
    return np.asarray(filled, np.float32).T.reshape(t, j, 3)


def _body_base(model, x_masked, mask, feats, frame_mask, pre=None) -> np.ndarray:
    """(T, J, 3) the gate's body-frame base (:func:`.gate.base_fill`; ``pre``: its pre-fill (1, D, T) when the
    caller has it) as ``infill`` puts it back in global positions (the run's root path)."""
    from inbetween_jax.models.cae.features import root_path_options, to_global
    from inbetween_jax.models.cae.gate import base_fill
    base = base_fill(model, np.asarray(x_masked, np.float32)[None], np.asarray(mask, np.float32)[None], pre=pre)[0]
    return to_global(base, model.normalizer, model.num_joints, feats.ref0, feats.yaw0, known_feats=feats.features,
                     frame_mask=frame_mask, known_track=(feats.ref, feats.yaw), **root_path_options(model.cfg.model))


def _shares(model_cfg, ref, frame_mask) -> list:
    from inbetween_jax.models.cae.masks import gap_ranges
    near, far = float(model_cfg.global_base_near), float(model_cfg.global_base_far)
    return [(int(a), int(b), travel_share(ref, a, b, near, far)) for a, b in gap_ranges(frame_mask)]


def base_positions(model, x_masked, mask, feats, frame_mask, pre=None) -> np.ndarray:
    """(T, J, 3) the run's base for every gap in global positions: the body-frame base, with the global fill's
    share where ``model.global_base_far`` > 0.  x_masked, mask (D, T): the normalised masked clip and its mask;
    feats: the file's :class:`~inbetween_jax.models.cae.features.MotionFeatures`; frame_mask (T,) 1 = known;
    pre: the network's pre-fill (1, D, T) (``base_fill(..., edge_fade=False)``) when the caller has it."""
    body = _body_base(model, x_masked, mask, feats, frame_mask, pre)
    mc = model.cfg.model
    if not enabled(mc):
        return body
    glob = global_fill(feats.global_pos, frame_mask, mc.global_base_fade)
    out = body.copy()
    for a, b, share in _shares(mc, feats.ref, frame_mask):
        out[a:b] += share * (glob[a:b] - body[a:b])
    return out


def apply(model, pos, x_masked, mask, feats, frame_mask, gated: list) -> np.ndarray:
    """``pos`` (T, J, 3), the gated fill in global positions, with each gap's base part moved onto the global
    fill by its share (module docstring).  ``gated``: the per-gap records of the gate and the match (``"gap"``,
    ``"gate_weight"``, ``"match_weight"``), each given ``global_share`` (the share) and ``global_weight`` (the
    part of the gap moved) in place.  Returns the new positions (``pos`` itself is not changed)."""
    mc = model.cfg.model
    body = _body_base(model, x_masked, mask, feats, frame_mask)
    glob = global_fill(feats.global_pos, frame_mask, mc.global_base_fade)
    shares = {(a, b): s for a, b, s in _shares(mc, feats.ref, frame_mask)}
    out = np.array(pos, np.float32, copy=True)
    for row in gated:
        a, b = row["gap"]
        share = shares.get((a, b), 0.0)
        w = (1.0 - row.get("gate_weight", 1.0)) * (1.0 - row.get("match_weight", 0.0)) * share
        out[a:b] += w * (glob[a:b] - body[a:b])
        row.update(global_share=round(share, 4), global_weight=round(w, 4))
    return out
