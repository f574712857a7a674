"""The CAE's out-of-distribution gate (:mod:`inbetween_jax.models.ood`): a score per gap and the blend of the
network's fill toward its Hermite base (:func:`base_fill`) as the score rises.

Context of a gap ``[a, b)`` in a normalised clip image (D, T): the feature columns (the CAE's own input space:
body-frame joint positions and root velocities) of the known frames ``a - 1, a - 4, a - 8`` before it and ``b,
b + 3, b + 7`` after it (clipped into the clip), plus the gap's length / 30.  The bank holds the same for random
gaps in the training clips.  ``ood.npz`` in the run (or shipped) folder holds bank and gate; ``model.ood_gate``
switches the blend on.  Instead of the bank, the score may be the root's floor speed at those frames
(:func:`floor_scorer`, ``inbetween calibrate-gate RUN_DIR --kind travel``).

The k-NN cap (``model.knn_gate``; :func:`knn_cap`): a second weight from the gap context's k-NN distance to the
training contexts, its thresholds the 90th percentile and the maximum of the validation subjects' distances
(:func:`knn_cap_thresholds`), and the gap keeps the smaller of the two weights.  A network trained on locomotion
may travel through a dance or a kata it never saw: there the root moves, so the speed gate opens, but the context
lies farther from the training motion than any validation gap's.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CONTEXT_FRAMES", "gap_context", "training_contexts", "base_fill", "gate_clips", "floor_scorer", "knn_cap",
           "knn_cap_thresholds", "KNN_CAP_PREFIX", "KNN_CAP_QUANTILES"]

KNN_CAP_PREFIX = "knn_cap_"          # ood.npz: the cap's ContextBank arrays and its gate_lo / gate_hi
KNN_CAP_QUANTILES = (0.9, 1.0)       # the cap's thresholds: these quantiles of the validation gaps' k-NN scores

CONTEXT_FRAMES = (-1, -4, -8, 0, 3, 7)     # offsets from a (negative) and from b (the rest)


def gap_context(x_norm, a, b) -> np.ndarray:
    """(N, 6 D + 1) contexts of gaps ``[a, b)`` (ints or (N,) arrays) in clips x_norm (N, D, T)."""
    x = np.asarray(x_norm, np.float32)
    n, _, t = x.shape
    a = np.broadcast_to(np.asarray(a), (n,))
    b = np.broadcast_to(np.asarray(b), (n,))
    cols = [np.clip(np.where(np.asarray(o) < 0, a + o, b + o), 0, t - 1) for o in CONTEXT_FRAMES]
    i = np.arange(n)
    feats = [x[i, :, c] for c in cols]                                          # each (N, D)
    return np.concatenate(feats + [((b - a) / 30.0)[:, None]], axis=1)


def floor_scorer(normalizer, num_joints: int, c: float = 1.0):
    """A :class:`~inbetween_jax.models.ood.FloorSpeedScore` of :func:`gap_context` contexts: the root's floor
    velocity (features ``3J``, ``3J + 1``: :mod:`.features`) at the context's known frames, ``c`` data units per
    frame."""
    from inbetween_jax.models.cae.features import num_features
    from inbetween_jax.models.ood import FloorSpeedScore
    rows = np.array([3 * num_joints, 3 * num_joints + 1])
    return FloorSpeedScore(num_features(num_joints), len(CONTEXT_FRAMES), rows,
                           np.asarray(normalizer.mean, np.float64)[rows], np.asarray(normalizer.std, np.float64)[rows],
                           float(c))


def training_contexts(bank, count: int = 4000, gaps=(15, 120), margin: int = 8, seed: int = 0) -> np.ndarray:
    """Contexts of ``count`` random gaps (length uniform in ``gaps``) in random clips of a
    :class:`~inbetween_jax.models.cae.features.ClipBank`."""
    rng = np.random.default_rng(seed)
    t = bank.clip_length
    out = []
    for lo in range(0, count, 512):
        m = min(512, count - lo)
        clips = bank.clips(rng.integers(0, len(bank.starts), m))
        g = rng.integers(gaps[0], min(gaps[1], t - 2 * margin) + 1, m)
        a = margin + (rng.random(m) * (t - 2 * margin - g)).astype(int)
        out.append(gap_context(clips, a, a + g))
    return np.concatenate(out)


def base_fill(model, x_norm, mask, edge_fade: bool = True, pre=None) -> np.ndarray:
    """The run's non-learned fill (``model.fill``: the limited cubic Hermite or the straight line) of the masked
    clips (N, D, T): the base the gate blends toward.  With ``model.base_edge_fade`` k > 0 (and ``edge_fade``) the
    body rows (the joint positions, not the root's velocities) of a Hermite fill give back the edge velocity the
    tangent limiter cut, fading as ``exp(-k frames)`` from each edge (``hermite_fill(edge_fade=k)``): the fill
    leaves and reaches each keyframe at the motion's own speed.  ``edge_fade=False``: the network's pre-fill;
    ``pre``: that pre-fill when the caller has it already (not computed again)."""
    from inbetween_jax.baselines import hermite_fill, linear_fill
    x = np.asarray(x_norm, np.float32) * mask
    if model.cfg.model.fill != "hermite":
        return np.asarray(linear_fill(x, mask), np.float32) if pre is None else np.asarray(pre, np.float32)
    out = np.array(hermite_fill(x, mask) if pre is None else pre, np.float32, copy=True)
    fade = float(getattr(model.cfg.model, "base_edge_fade", 0.0))
    if edge_fade and fade > 0:
        rows = slice(0, 3 * model.num_joints)
        m = np.broadcast_to(np.asarray(mask, np.float32), x.shape)
        out[..., rows, :] = np.asarray(hermite_fill(x[..., rows, :], m[..., rows, :], edge_fade=fade), np.float32)
    return out


def gate_clips(model, x_masked, mask, y):
    """The gate on every gap of clips x_masked (N, D, T) (the masked input) with fills y (N, D, T): each gap's
    columns become ``base + w (y - base)``.  Returns (gated y, per clip a list of ``{"gap": [a, b],
    "ood_score", "gate_weight"}``).

    Entries missing from a frame that keeps others (joint dropout) take the pre-fill wherever their row is known
    elsewhere in the clip: the gate is calibrated on whole missing frames only, and on the validation subjects a
    network that helps there can be 30x worse than its pre-fill at joint recovery (docs/results/gate.md).  Rows
    missing from the whole clip (joints a capture lacks) keep the network's fill, the only one there is."""
    from inbetween_jax.models.cae.masks import gap_ranges
    bank, gate = model.gate
    cap = getattr(model, "knn_cap", None) if getattr(model.cfg.model, "knn_gate", False) else None
    m = np.broadcast_to(np.asarray(mask, np.float32), np.shape(y))
    frames = (m.max(axis=1) > 0.5).astype(np.float32)                       # (N, T) 1 = some known
    pre = base_fill(model, x_masked, m, edge_fade=False)
    base = base_fill(model, x_masked, m, pre=pre)
    partial = (m < 0.5) & (frames[:, None, :] > 0.5) & (m.max(axis=2, keepdims=True) > 0.5)
    out, info = np.where(partial, pre, np.asarray(y, np.float32)).astype(np.float32), []
    for i in range(len(out)):
        rows = []
        for a, b in gap_ranges(frames[i]):
            ctx = gap_context(x_masked[i:i + 1], a, b)
            score = float(bank.score(ctx)[0])
            w, row = float(gate.weight(score)), {"gap": [int(a), int(b)], "ood_score": score}
            if cap is not None:
                knn = float(cap[0].score(ctx)[0])
                row.update(knn_score=knn, knn_weight=float(cap[1].weight(knn)))
                w = min(w, row["knn_weight"])
            out[i, :, a:b] = base[i, :, a:b] + w * (out[i, :, a:b] - base[i, :, a:b])
            rows.append(dict(row, gate_weight=w))
        info.append(rows)
    return out, info


def knn_cap_thresholds(knn_scores, quantiles=KNN_CAP_QUANTILES):
    """The k-NN cap's :class:`~inbetween_jax.models.ood.Gate` from the validation gaps' k-NN scores: the learned
    fill whole up to their ``quantiles[0]`` quantile, none beyond their ``quantiles[1]`` (the farthest)."""
    from inbetween_jax.models.ood import Gate
    lo, hi = (float(np.quantile(np.asarray(knn_scores, np.float64), q)) for q in quantiles)
    return Gate(lo, max(hi, lo + 1e-6))


def knn_cap(run_dir: str):
    """``(ContextBank, Gate)`` of the k-NN cap in ``run_dir/ood.npz``, or None when it holds none."""
    from inbetween_jax.models.ood import ContextBank, Gate, optional_gate_arrays
    lo, hi = f"{KNN_CAP_PREFIX}gate_lo", f"{KNN_CAP_PREFIX}gate_hi"
    a = optional_gate_arrays(run_dir, KNN_CAP_PREFIX, (lo, hi))
    if a is None:
        return None
    return ContextBank.from_arrays(a, KNN_CAP_PREFIX + "bank_"), Gate(float(a[lo]), float(a[hi]))
