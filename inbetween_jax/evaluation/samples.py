"""Metrics of a stochastic in-betweener's N samples of the same keyframes (the S-CVAE's "samples" table).

For S samples q (S, B, L, J, 4), r (S, B, L, 3) of the transition after frame ``n_past - 1`` of B windows
(:func:`sample_metrics`):

* ``APD`` (m): average pairwise distance of the whole motions (:func:`inbetween_jax.metrics.apd`);
* ``pairwise_cm``: the mean over windows, sample pairs, frames and joints of the distance between two samples'
  joints -- the animator's "how different are they", in the units of the error beside it;
* ``mean_L2P`` / ``best_L2P``: L2P averaged over the samples, and of the best sample per window (best-of-N,
  the window's lowest L2P), both then averaged over windows;
* ``mean_cm`` / ``best_cm``: the same with the mean joint position error (cm);
* ``reach`` / ``reach_truth``: the share of samples whose step into the target keyframe is at most
  ``SNAP_FACTOR`` times the median step of their own frames (joint positions) -- samples that arrive, rather
  than snap onto the key -- and the share of windows whose captured motion passes the same rule (real motion
  that speeds up into the key fails it too: 76-92 % pass on the test windows, 90-99 % on the validation
  subjects', ``experiments/scvae_arrival.py``);
* ``foot_slide_mean`` / ``foot_slide_worst``: foot sliding (cm / frame, ground-truth contacts) of the average
  sample and of the worst sample per window set (realism per sample);
* ``steps`` / ``steps_truth``: foot lift-offs per window from the start keyframe to the target
  (:func:`inbetween_jax.metrics.steps.lift_offs`), of the samples and of the captured motion: a fill that walks
  steps, one that glides does not.
"""
from __future__ import annotations

import jax
import numpy as np

from inbetween_jax import metrics
from inbetween_jax.evaluation.lafan1 import _fk
from inbetween_jax.metrics.steps import lift_offs

__all__ = ["SNAP_FACTOR", "sample_metrics", "pairwise_joint_distance", "per_window_l2p", "reach_share", "step_lengths",
           "sample_spread", "window_positions"]

SNAP_FACTOR = 2.0
CM_TO_M = 0.01


def window_positions(windows, quats, root) -> np.ndarray:
    """Global joint positions (..., J, 3) of local quaternions and root positions on the windows' skeleton."""
    return _fk(windows, quats, root)[1]


def pairwise_joint_distance(pos: np.ndarray) -> float:
    """Mean distance between two different samples' joints: pos (S, B, L, J, 3) -> mean over windows, ordered
    sample pairs i != j, frames and joints of ||pos_i - pos_j||.  0.0 for one sample."""
    s = pos.shape[0]
    if s < 2:
        return 0.0
    total = sum(np.linalg.norm(pos[i] - pos[j], axis=-1).mean() for i in range(s) for j in range(s) if i != j)
    return float(total / (s * (s - 1)))


def per_window_l2p(pred_pos, gt_pos, x_mean, x_std) -> np.ndarray:
    """L2P of each window: pred_pos (..., B, L, J, 3), gt_pos (B, L, J, 3) -> (..., B)
    (:func:`inbetween_jax.metrics.l2p` of one window at a time)."""
    one = jax.vmap(lambda p, g: metrics.l2p(p[None], g[None], x_mean, x_std))
    pred = np.asarray(pred_pos)
    lead = pred.shape[:-4]
    flat = pred.reshape((-1,) + pred.shape[-4:])
    return np.stack([np.asarray(one(p, gt_pos)) for p in flat]).reshape(lead + (pred.shape[-4],))


def step_lengths(full_pos: np.ndarray) -> np.ndarray:
    """(..., L + 2, J, 3) joint positions from keyframe to keyframe -> (..., L + 1) mean joint displacement of
    each step."""
    return np.linalg.norm(np.diff(full_pos, axis=-3), axis=-1).mean(-1)


def reach_share(full_pos: np.ndarray, factor: float = SNAP_FACTOR) -> float:
    """Share of the samples that arrive at the target keyframe.  full_pos (S, B, L + 2, J, 3): the start
    keyframe, the L generated frames and the target keyframe.  A sample arrives when its last step (last
    generated frame -> target, mean joint displacement) is at most ``factor`` times the median of its steps
    between generated frames."""
    steps = step_lengths(full_pos)                                              # (S, B, L + 1)
    inner = np.median(steps[:, :, 1:-1], axis=-1) if steps.shape[2] > 2 else steps[:, :, 0]
    return float(np.mean(steps[:, :, -1] <= factor * np.maximum(inner, 1e-9)))


def sample_metrics(windows, n_past: int, n_trans: int, q, r, x_mean, x_std) -> dict:
    """The module docstring's columns for samples q (S, B, L, J, 4), r (S, B, L, 3) (or one sample without
    the S axis) of every window's transition between frames ``n_past - 1`` and ``n_past + n_trans``."""
    q, r = np.asarray(q), np.asarray(r)
    if q.ndim == 4:
        q, r = q[None], r[None]
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(r))):
        raise FloatingPointError("samples contain NaN or inf; refusing to score them")
    lo, hi = n_past, n_past + n_trans
    truth = window_positions(windows, windows.local_quats[:, lo - 1:hi + 1], windows.root_pos[:, lo - 1:hi + 1])
    key, gt, tgt = truth[:, :1], truth[:, 1:-1], truth[:, -1:]       # keyframe, transition (B, L, J, 3), target
    pos = np.stack([window_positions(windows, qs, rs) for qs, rs in zip(q, r)])                     # (S, B, L, J, 3)
    s = pos.shape[0]
    full = np.concatenate([np.broadcast_to(key, (s,) + key.shape), pos, np.broadcast_to(tgt, (s,) + tgt.shape)], 2)
    l2p = per_window_l2p(pos, gt, x_mean, x_std)                                              # (S, B)
    cm = np.linalg.norm(pos - gt, axis=-1).mean((-1, -2))                                     # (S, B)
    feet = windows.skeleton.foot_joints()
    contacts = windows.contacts[:, lo - 1:hi + 1]
    slide = [float(metrics.foot_sliding(f, feet, contacts=contacts)) for f in full]
    ankles = (feet[0], feet[2])
    return {"APD": float(metrics.apd(pos, scale=CM_TO_M)) if s > 1 else 0.0,
            "pairwise_cm": pairwise_joint_distance(pos),
            "mean_L2P": float(l2p.mean()), "best_L2P": float(l2p.min(0).mean()),
            "mean_cm": float(cm.mean()), "best_cm": float(cm.min(0).mean()),
            "reach": reach_share(full), "reach_truth": reach_share(truth[None]),
            "foot_slide_mean": float(np.mean(slide)),
            "foot_slide_worst": float(np.max(slide)), "steps": float(np.mean(lift_offs(full, ankles))),
            "steps_truth": float(np.mean(lift_offs(truth, ankles)))}


def sample_spread(motions) -> dict:
    """How different the samples of one in-between are, for ``infill.json``: ``samples_pairwise_cm`` (mean joint
    distance between two samples over the frames) and ``samples_spread_cm`` (each sample's mean joint distance to
    the others: the largest is the most unusual choice).  motions: per sample one Motion, or a tuple of Motions
    (the characters of a two-person sample, their joints pooled); the same frames in every sample."""
    from inbetween_jax.data.features import detect_unit_scale
    if len(motions) < 2:
        return {}
    groups = [m if isinstance(m, (tuple, list)) else (m,) for m in motions]
    cm = detect_unit_scale(groups[0][0].skeleton)
    pos = np.stack([np.concatenate([np.asarray(m.global_positions()) for m in g], 1) for g in groups]) * cm
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1).mean((-1, -2))              # (S, S), zero diagonal
    each = d.sum(1) / (len(motions) - 1)
    return {"samples_pairwise_cm": round(float(each.mean()), 3),
            "samples_spread_cm": [round(float(x), 3) for x in each]}
