"""The CAE inside a file, as ``inbetween infill --model cae`` fills it: per gap, the error of
:func:`~inbetween_jax.models.cae.infer.process_motion`'s global joint positions (gate, motion matching and root bound
as the run's config says) over three non-learned fills: its base, the fill the gate falls back to
(:func:`~inbetween_jax.models.cae.global_base.base_positions`: :func:`~inbetween_jax.models.cae.gate.base_fill`
through the same root path, the limited cubic Hermite with the run's edge fades, ``model.base_edge_fade`` and
``model.root_edge_fade``, moved onto the global Hermite where the body stays near its place,
``model.global_base_near`` / ``_far``); the limited cubic Hermite without them
(body and root path; the CAE's base until 2026-12-07, and the network's pre-fill); and straight lines between the
global joint positions beside the gap.  The bench writes these as ``per_window`` rows of its own split names (``"test, inside a file"`` /
``"validation, inside a file"``).

    gap_records(model, motions, seconds=(1, 2)) -> list of {"name", "frames", "ratio", "x_limited", "x_straight",
                                                              "matched",
                                                              "step_change", "step_change_capture",
                                                              "ood_score", "gate_weight"}

The experiments that score the CAE's gaps inside files (``experiments/cae_*.py``) take the same gaps
(:func:`gap_starts`) and put fills back into global positions the same way (:func:`gap_positions`).
"""
from __future__ import annotations

import numpy as np

__all__ = ["gap_records", "gap_starts", "gap_positions", "keyframe_step_change", "base_rows", "SECONDS",
           "MARGIN_FRAMES", "BASES"]

SECONDS = (1, 2)          # gap lengths, as the validation choice of the match (experiments/cae_motion_match.py)
MARGIN_FRAMES = 10        # known frames kept before the first gap and after the last
BASES = (("ratio", "its base"), ("x_limited", "the limited Hermite fill"), ("x_straight", "straight lines"))
"""gap_records' ratios and the base each divides by ("its base": the fill the gate falls back to)."""


def gap_starts(num_frames: int, length: int) -> range:
    """First frames of the ``length``-frame gaps scored in a file of ``num_frames`` frames: every ``max(length,
    30)`` frames, :data:`MARGIN_FRAMES` known frames kept before the first and after the last."""
    return range(MARGIN_FRAMES, num_frames - length - MARGIN_FRAMES, max(length, 30))


def gap_positions(model, y_norm, feats, frame_mask, root_edge_fade: float | None = None) -> np.ndarray:
    """(T, J, 3) global joint positions of one filled clip ``y_norm`` (D, T, normalised) as ``infill`` puts them
    back: the known frames on their own root track (``feats``: the file's
    :class:`~inbetween_jax.models.cae.features.MotionFeatures`), each gap's root held to the run's
    ``model.root_bound`` around the Hermite root path (``model.root_edge_fade``, or ``root_edge_fade`` when given:
    its edge tangents)."""
    from inbetween_jax.models.cae.features import root_path_options, to_global
    roots = root_path_options(model.cfg.model)
    if root_edge_fade is not None:
        roots["root_edge_fade"] = float(root_edge_fade)
    return to_global(y_norm, model.normalizer, model.num_joints, feats.ref0, feats.yaw0, known_feats=feats.features,
                     frame_mask=frame_mask, known_track=(feats.ref, feats.yaw), **roots)


def keyframe_step_change(pos, lo: int, hi: int) -> float:
    """How much the joints' steps change across the keyframes of the gap ``[lo, hi)`` in global positions pos
    (T, J, 3), in its units per frame: ``|(p[lo] - p[lo-1]) - (p[lo-1] - p[lo-2])|`` and the same at ``hi``, mean
    over joints and both edges.  A fill that stops a moving joint at the keyframe shows a large change; the
    capture's own change there is the reference (needs two frames beyond each edge)."""
    a = np.linalg.norm(pos[lo] - 2 * pos[lo - 1] + pos[lo - 2], axis=-1).mean()
    b = np.linalg.norm(pos[hi + 1] - 2 * pos[hi] + pos[hi - 1], axis=-1).mean()
    return 0.5 * float(a + b)


def gap_records(model, motions, seconds=SECONDS, limit: int | None = None) -> list:
    """One record per gap: every ``max(g, 30)`` frames of each motion (at its own rate), ``g`` the gap length in
    frames; ``limit`` caps the gaps per length (quick benches).  Motions must be on the model's skeleton."""
    from inbetween_jax.geometry import forward_kinematics
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.models.cae.gate import base_fill
    from inbetween_jax.models.cae.global_base import base_positions
    from inbetween_jax.models.cae.infer import process_motion
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    j = model.num_joints
    out = []
    for sec in seconds:
        n_len = 0
        for m in motions:
            g = int(round(sec * float(m.fps)))
            gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
            for lo in gap_starts(m.num_frames, g):
                if limit is not None and n_len >= limit:
                    break
                n_len += 1
                fm = gap_frames(m.num_frames, [(lo, lo + g)])
                res = process_motion(model, m, [(lo, lo + g)])
                feats = body_frame_features(m, known=fm > 0.5)
                mask = frame_mask_image(fm, j)
                x = model.normalizer(feats.features).T.astype(np.float32)
                xm = (x * mask)[None]
                pre = base_fill(model, xm, mask[None], edge_fade=False)
                base = base_positions(model, xm[0], mask, feats, fm, pre=pre)
                limited = gap_positions(model, pre[0], feats, fm, root_edge_fade=0.0)
                w = (np.arange(1, g + 1) / (g + 1))[:, None, None]
                straight = gp[lo - 1] + w * (gp[lo + g] - gp[lo - 1])

                def err(pos):
                    return float(np.linalg.norm(pos[lo:lo + g] - gp[lo:lo + g], axis=-1).mean())
                e = err(res["positions"])
                out.append({"name": str(m.source), "frames": g, "ratio": e / max(err(base), 1e-9),
                            "x_limited": e / max(err(limited), 1e-9),
                            "x_straight": e / max(float(np.linalg.norm(straight - gp[lo:lo + g], axis=-1).mean()),
                                                  1e-9),
                            "matched": any(r.get("match_weight", 0.0) > 0.5 for r in res["gaps_ood"]),
                            "step_change": keyframe_step_change(res["positions"], lo, lo + g),
                            "step_change_capture": keyframe_step_change(gp, lo, lo + g),
                            **{k: float(res["gaps_ood"][0][k]) for k in ("ood_score", "gate_weight")
                               if res["gaps_ood"] and k in res["gaps_ood"][0]}})
    return out


def base_rows(records, data: str, split: str) -> list:
    """Worst-case rows (:func:`inbetween_jax.evaluation.worst_case.worst_case_rows`, table ``per_window``, model
    ``cae``) of :func:`gap_records`' records against each of :data:`BASES` in turn, split ``split``."""
    from inbetween_jax.evaluation.worst_case import worst_case_rows
    return [row for key, base in BASES
            for row in worst_case_rows([dict(r, ratio=r[key]) for r in records], "per_window", data, "cae", base,
                                       split)]
