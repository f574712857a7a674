"""The CAE paper's infilling protocol (Kaufmann et al. 2020, Tables 1 and 2) on clip images of the CAE
representation (:mod:`inbetween_jax.models.cae.features`).

Test clips: the test split's motions cut in 240-frame windows at stride 120 (:func:`test_clips`).  Errors
are the root-aligned 3D joint errors (cm) of the body-frame joint positions (the representation's position
rows: root projected on the floor, facing +Z), mean and std over every (frame, joint) scored --
``metrics.mpjpe(root_relative=False)`` (:func:`position_error`).

* Table 1: one gap centred in the clip, scored over the gap frames (0 frames: the clean clip is
  reconstructed and every frame is scored; not defined for a baseline that copies its input).
  ``GAPS`` = 0 / 60 / 120 frames (the paper's, at 60 Hz); ``GAPS_SECONDS`` = 0 / 30 / 60 frames, the same
  durations at 30 Hz.
* Table 2 (de-noising): N(0, sigma^2) noise on the position rows in normalised units (``SIGMAS``), or each
  joint of each frame dropped with probability p (``PS``); every frame is scored.  The draws come from one
  ``np.random.default_rng(seed)`` (:func:`corruptions`) and are the same for every method.
* Bone lengths of the clean-clip reconstruction (:func:`inbetween_jax.metrics.bone_length_spread`).

A method is ``predict(x_norm (N, D, T), mask (N, D, T)) -> (N, D, T)`` (1 = known).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from inbetween_jax.models.cae.features import body_frame_features, body_positions
from inbetween_jax.models.cae.masks import add_position_noise, dropout_mask, frame_mask_image, gap_frames

__all__ = ["GAPS", "GAPS_SECONDS", "SIGMAS", "PS", "CLIP_LENGTH", "CLIP_STRIDE", "test_clips", "position_error",
           "corruptions", "evaluate_method"]

GAPS = (0, 60, 120)
GAPS_SECONDS = (0, 30, 60)
SIGMAS = (1.0, 1.5)
PS = (0.3, 0.5)
CLIP_LENGTH, CLIP_STRIDE = 240, 120


def test_clips(motions, normalizer, length: int = CLIP_LENGTH, stride: int = CLIP_STRIDE, limit=None) -> np.ndarray:
    """Normalised clip images (N, D, length) of every window at ``stride`` of ``motions`` (first ``limit``)."""
    out = []
    for m in motions:
        f = normalizer(body_frame_features(m).features)
        for s in range(0, f.shape[0] - length + 1, stride):
            out.append(f[s:s + length].T)
    if not out:
        raise ValueError(f"no test motion has {length} frames")
    x = np.stack(out).astype(np.float32)
    return x[:limit] if limit else x


def position_error(pred, target, normalizer, num_joints: int, frames=None) -> tuple:
    """``(mean, std)`` cm of the body-frame joint errors: pred, target (N, D, T) normalised; frames (N, T)
    weights of the scored frames (None: all)."""
    from inbetween_jax.metrics import mpjpe
    mean, std = mpjpe(body_positions(pred, normalizer, num_joints), body_positions(target, normalizer, num_joints),
                      mask=frames, root_relative=False)
    return float(mean), float(std)


def corruptions(x, num_joints: int, seed: int = 0) -> dict:
    """Table 2 inputs: ``{"sigma=1.0": (noisy x, all-ones mask), ..., "p=0.3": (x, dropout mask), ...}``."""
    n, _, t = x.shape
    rng = np.random.default_rng(seed)
    out = {f"sigma={s}": (add_position_noise(rng, x, num_joints, s), np.ones_like(x)) for s in SIGMAS}
    for p in PS:
        out[f"p={p}"] = (x, dropout_mask(rng, (n, t), num_joints, p))
    return out


def evaluate_method(predict: Callable, x, corrupt: dict, normalizer, num_joints: int, parents,
                    learned: bool = True) -> dict:
    """One method through the protocol.

    x: (N, D, T) clean normalised clips; corrupt: :func:`corruptions` of ``x``; learned: False for a
    baseline that returns its input where nothing is missing (its 0-frame cell is None and its noise cells
    are the noisy input's own error).  Returns ``{"table1": [(mean, std) or None per GAPS],
    "table1_seconds": [... per GAPS_SECONDS], "table2": {corruption: (mean, std)}, "bones": dict or None}``.
    """
    n, _, t = x.shape
    ones = np.ones_like(x)
    tables = {}
    for name, gaps in (("table1", GAPS), ("table1_seconds", GAPS_SECONDS)):
        row = []
        for g in gaps:
            if g == 0:
                row.append(position_error(predict(x, ones), x, normalizer, num_joints) if learned else None)
                continue
            a = (t - g) // 2
            fm = np.broadcast_to(gap_frames(t, [(a, a + g)]), (n, t))
            row.append(position_error(predict(x, frame_mask_image(fm, num_joints)), x, normalizer, num_joints,
                                      frames=1.0 - fm))
        tables[name] = row
    tables["table2"] = {k: position_error(predict(inp * 1.0, m) if learned or k.startswith("p") else inp, x,
                                          normalizer, num_joints) for k, (inp, m) in corrupt.items()}
    tables["bones"] = None
    if learned:
        from inbetween_jax.metrics import bone_length_spread
        b = bone_length_spread(body_positions(predict(x, ones), normalizer, num_joints),
                               body_positions(x, normalizer, num_joints), tuple(int(p) for p in parents))
        tables["bones"] = {"mean_abs_median_dev_cm": float(b["median_dev"]), "mean_std_cm": float(b["std"]),
                           "gt_mean_std_cm": float(b["gt_std"]), "mean_iqr_cm": float(b["iqr"])}
    return tables
