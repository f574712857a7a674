"""LaFAN1-style transition protocols: the official LaFAN1 baseline table and the S-CVAE paper's Table 1 layout.

A method is evaluated from its predicted transition frames only. Ground truth comes from benchmark
windows (:func:`inbetween_jax.data.load_dataset` with ``split="benchmark"``): the last past keyframe is
frame ``n_past - 1``, the transition is frames ``n_past .. n_past + L - 1`` and the target keyframe is
frame ``n_past + L``.

Units: L2P is normalised (unitless), L2Q is in quaternion units, NPSS unitless; ADE, SLDE and APD are
in metres (the data are in cm, scaled by 0.01), foot slide in cm per frame (GT contact labels).
Accuracy metrics of stochastic methods are averaged over their samples.
"""
from __future__ import annotations

import numpy as np

from inbetween_jax import metrics
from inbetween_jax.baselines import interpolate_transition, zero_velocity_transition
from inbetween_jax.data.windows import MotionWindows
from inbetween_jax.geometry.kinematics import forward_kinematics, local_positions

CM_TO_M = 0.01
TABLE_COLUMNS = ("APD", "L2P", "L2Q", "ADE", "SLDE", "NPSS", "FootSlide")
BASELINES = {"Zero-velocity": zero_velocity_transition, "Slerp": interpolate_transition}


def _fk(windows: MotionWindows, quats, root):
    gq, gp = forward_kinematics(np.asarray(quats, np.float64),
                                local_positions(np.asarray(root, np.float64), windows.skeleton.offsets),
                                windows.parents)
    return gq, gp


def official_errors(windows: MotionWindows, n_past: int, n_trans: int, pred_quats, pred_root,
                    x_mean, x_std) -> dict:
    """L2Q, L2P, NPSS of one deterministic prediction, exactly as the official ``benchmarks.py``.

    pred_quats: (B, L, J, 4) local quaternions of the transition; pred_root: (B, L, 3).
    x_mean, x_std: (1, J*3, 1) L2P statistics.
    """
    lo, hi = n_past, n_past + n_trans
    gt_q, gt_p = _fk(windows, windows.local_quats[:, lo:hi], windows.root_pos[:, lo:hi])
    pq, pp = _fk(windows, pred_quats, pred_root)
    b = gt_q.shape[0]
    return {"L2Q": float(metrics.l2q(pq, gt_q)), "L2P": float(metrics.l2p(pp, gt_p, x_mean, x_std)),
            "NPSS": float(metrics.npss(gt_q.reshape(b, n_trans, -1), pq.reshape(b, n_trans, -1)))}


def official_baseline_table(windows: MotionWindows, x_mean, x_std, lengths=(5, 15, 30, 45),
                            n_past: int = 10) -> list:
    """Rows ``{"method", "frames", "L2Q", "L2P", "NPSS"}`` for zero-velocity and interpolation."""
    rows = []
    for name, fn in BASELINES.items():
        for length in lengths:
            _check_length(windows, n_past, length)
            q, r = fn(windows.local_quats.astype(np.float64), windows.root_pos.astype(np.float64), n_past, length)
            rows.append({"method": name, "frames": length,
                         **official_errors(windows, n_past, length, q, r, x_mean, x_std)})
    return rows


def transition_metrics(windows: MotionWindows, n_past: int, n_trans: int, pred_quats, pred_root,
                       x_mean, x_std) -> dict:
    """The S-CVAE Table 1 columns for one method.

    pred_quats: (S, B, L, J, 4) or (B, L, J, 4); pred_root: (S, B, L, 3) or (B, L, 3) -- S samples.
    Returns ``{"APD", "L2P", "L2Q", "ADE", "SLDE", "NPSS", "FootSlide"}`` (APD 0 for one sample).
    """
    pred_quats, pred_root = np.asarray(pred_quats), np.asarray(pred_root)
    if pred_quats.ndim == 4:
        pred_quats, pred_root = pred_quats[None], pred_root[None]
    _check_length(windows, n_past, n_trans)
    if not (np.all(np.isfinite(pred_quats)) and np.all(np.isfinite(pred_root))):
        raise FloatingPointError("prediction contains NaN or inf; refusing to score it")
    lo, hi = n_past, n_past + n_trans
    gt_q, gt_p = _fk(windows, windows.local_quats[:, lo:hi], windows.root_pos[:, lo:hi])
    b = gt_q.shape[0]
    feet = windows.skeleton.foot_joints()
    # frames keyframe .. target so stepping into and out of the gap counts as motion
    key_q = windows.local_quats[:, n_past - 1:n_past]
    key_r = windows.root_pos[:, n_past - 1:n_past]
    tgt_q = windows.local_quats[:, hi:hi + 1]
    tgt_r = windows.root_pos[:, hi:hi + 1]
    contacts = windows.contacts[:, n_past - 1:hi + 1]
    per_sample, positions = [], []
    for q, r in zip(pred_quats, pred_root):
        pq, pp = _fk(windows, q, r)
        positions.append(pp)
        _, full = _fk(windows, np.concatenate([key_q, q, tgt_q], 1), np.concatenate([key_r, r, tgt_r], 1))
        per_sample.append({
            "L2P": float(metrics.l2p(pp, gt_p, x_mean, x_std)),
            "L2Q": float(metrics.l2q(pq, gt_q)),
            "ADE": float(metrics.ade(pp, gt_p, scale=CM_TO_M)),
            "SLDE": float(metrics.slde(pp, gt_p, scale=CM_TO_M)),
            "NPSS": float(metrics.npss(gt_q.reshape(b, n_trans, -1), pq.reshape(b, n_trans, -1))),
            "FootSlide": float(metrics.foot_sliding(full, feet, contacts=contacts)),
        })
    row = {k: float(np.mean([s[k] for s in per_sample])) for k in per_sample[0]}
    row["APD"] = float(metrics.apd(np.stack(positions), scale=CM_TO_M)) if len(positions) > 1 else 0.0
    return {k: row[k] for k in TABLE_COLUMNS}


def baseline_table1(windows: MotionWindows, x_mean, x_std, lengths=(10, 30, 50), n_past: int = 10) -> list:
    """Slerp and zero-velocity rows of the S-CVAE Table 1 layout (one past keyframe, frame n_past-1)."""
    rows = []
    for length in lengths:
        for name, fn in BASELINES.items():
            q, r = fn(windows.local_quats.astype(np.float64), windows.root_pos.astype(np.float64), n_past, length)
            rows.append({"method": name, "frames": length,
                         **transition_metrics(windows, n_past, length, q, r, x_mean, x_std)})
    return rows


def _check_length(windows: MotionWindows, n_past: int, n_trans: int) -> None:
    if n_trans < 1 or n_past < 1 or n_past + n_trans >= windows.window:
        raise ValueError(f"a {n_trans}-frame transition after {n_past} past frames needs windows longer than "
                         f"{n_past + n_trans} frames; these have {windows.window}")
