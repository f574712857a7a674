"""The interaction model judged per window and per sample: the worst case and N samples of each window.

:func:`per_window_rows`: each window's joint error over interpolation's (the bench's per-window rows, the gate's
calibration measure).  :func:`sample_table`: the model as a generative model.

Per length, on windows of the real-pair protocol (true gap): mean- and best-of-N L2P (best: each window's lowest
over its samples, then the mean over windows) as ratios to interpolation's, APD (m, both characters' positions in
the common space), the mean pairwise joint distance between samples (cm) and the interaction classifier's score of
every sample (the mean over samples and windows, as a multiple of ground truth's on the same windows).  Used by the
bench's samples rows and ``experiments/interaction_samples.py`` (the sampled mode chosen on the validation take).
"""
from __future__ import annotations

import numpy as np

__all__ = ["window_l2p", "window_errors_cm", "per_window_rows", "sample_table", "bench_rows"]


def _common(feats, b) -> np.ndarray:
    """Joint positions (B, 2, L, J, 3) of features ``feats`` (B, 2, L, J, 9) of window ``b``'s characters in
    character A's key space (the common space)."""
    import jax.numpy as jnp
    from inbetween_jax.models.interaction.features import to_common_space
    return np.asarray(to_common_space(jnp.asarray(feats), b["rel_R"], b["rel_t"]))[..., :3]


def _truth(b, L: int) -> np.ndarray:
    """The common-space joint positions of window ``b``'s L gap frames."""
    from inbetween_jax.evaluation.interaction import N_INPUT
    return _common(b["x"][:, :, N_INPUT:N_INPUT + L], b)


def _l2p(P, G, std) -> np.ndarray:
    """Per window L2P of common-space positions P against G (B, 2, L, J, 3); std: the L2P scale (D,)."""
    z = (P.reshape(P.shape[:3] + (-1,)) - G.reshape(G.shape[:3] + (-1,))) / std          # (B, 2, L, D); mu cancels
    return np.sqrt(np.sum(z ** 2, -1)).mean((1, 2))


def window_l2p(pred, b, stats) -> np.ndarray:
    """Per window: L2P of ``pred`` (B, 2, L, J, 9) against the window's ground truth (the mean of both characters,
    common space), so that its mean over windows is :func:`~inbetween_jax.evaluation.interaction.pair_l2p`."""
    return _l2p(_common(pred, b), _truth(b, pred.shape[2]), np.asarray(stats[1], np.float64))


def window_errors_cm(pred, b) -> np.ndarray:
    """Per window: mean joint position error (cm) over both characters and the gap frames of ``pred`` (B, 2, L,
    J, 9) against window ``b``'s ground truth, in the common space (positions in metres)."""
    return 100.0 * np.linalg.norm(_common(pred, b) - _truth(b, pred.shape[2]), axis=-1).mean((1, 2, 3))


def per_window_rows(trained, method, windows, data: str, lengths=(30, 50)) -> tuple:
    """Worst-case rows (:mod:`inbetween_jax.evaluation.worst_case`) of a bench ``method``: each test window's
    joint error (one sample, true gap) over per-character interpolation's, per length; plus the validation take
    from a gated run's ``ood_calibration.json`` at the gate's weights.  Returns (rows, markdown)."""
    import jax
    from inbetween_jax.evaluation.interaction import N_INPUT
    from inbetween_jax.evaluation.worst_case import worst_case_markdown, worst_case_rows
    from inbetween_jax.models.interaction.gate import interpolation_base
    from inbetween_jax.models.ood_runs import calibration_worst_case
    recs = []
    for L in lengths:
        b = windows.get(L)
        if not b:
            continue
        pred = np.asarray(method(b, -(-L // trained.cfg.data.n_pred), 1, jax.random.key(L)))[0, :, :, :L]
        base = window_errors_cm(interpolation_base(b["x"][:, :, :N_INPUT], b["keypose"], L), b)
        recs += [{"name": n, "frames": L, "ratio": float(e / max(g, 1e-6))}
                 for n, e, g in zip(b["names"], window_errors_cm(pred, b), base)]
    rows = worst_case_rows(recs, "per_window", data, "interaction", "interpolation", "test")
    val = calibration_worst_case(trained.run_dir, trained.gate if trained.cfg.model.ood_gate else None,
                                 "interaction", "interpolation", split="validation take")
    md = worst_case_markdown(rows, "Per-window ratio to interpolation, test takes (true gap, one sample)")
    if val:
        md += "\n\n" + worst_case_markdown(val, "Per-window ratio to interpolation, validation take (gated)")
    return rows + val, md


def _scores(cls, b, pred):
    """Classifier score of each window's clip: last context frame + ``pred`` (B, 2, L, J, 9), common space."""
    import jax.numpy as jnp
    from inbetween_jax.evaluation.interaction import N_INPUT, classify_windows, to_common_space
    clip = np.concatenate([b["x"][:, :, N_INPUT - 1:N_INPUT], pred], 2)
    common = to_common_space(jnp.asarray(clip, jnp.float32), b["rel_R"], b["rel_t"])
    return np.asarray(classify_windows(cls[0], cls[1], common)[0]).mean(1)                 # (B,)


def sample_table(method, windows, stats, cls, num: int = 10, lengths=(30, 50), seed: int = 0) -> list:
    """Rows ``{"frames", "windows", "fill_l2p", "mean_l2p", "best_l2p", "interp_l2p", "apd_m", "pairwise_cm",
    "score", "score_gt"}`` of ``method`` (a bench method, ``num`` samples) on ``windows[L]``; ``fill_l2p`` is
    sample 0's, the deterministic fill; cls: (graphdef, params) of the bench's interaction classifier."""
    import jax
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.evaluation.samples import pairwise_joint_distance
    from inbetween_jax.metrics import apd
    std = np.asarray(stats[1], np.float64)
    rows = []
    for L in lengths:
        b = windows.get(L)
        if not b:
            continue
        steps = -(-L // 10)
        pred = np.asarray(method(b, steps, num, jax.random.fold_in(jax.random.key(seed), L)))[:, :, :, :L]
        common, truth = np.stack([_common(p, b) for p in pred]), _truth(b, L)             # (N, B, 2, L, J, 3)
        per = np.stack([_l2p(c, truth, std) for c in common])                              # (N, B)
        interp = window_l2p(proto.interpolation_method(b, steps, 1, None)[0][:, :, :L], b, stats)
        rows.append({"frames": L, "windows": int(per.shape[1]), "fill_l2p": float(per[0].mean()),
                     "mean_l2p": float(per.mean()), "best_l2p": float(per.min(0).mean()),
                     "interp_l2p": float(interp.mean()),
                     "apd_m": float(apd(common.reshape(common.shape[:2] + (-1,)))),
                     "pairwise_cm": 100.0 * pairwise_joint_distance(common),
                     "score": float(np.mean([_scores(cls, b, p).mean() for p in pred])),
                     "score_gt": float(_scores(cls, b, b["x"][:, :, proto.N_INPUT:proto.N_INPUT + L]).mean())})
    return rows


def bench_rows(table_rows, data: str, variant: str) -> tuple:
    """The bench's ``table: "samples"`` rows (bench.json) and markdown of :func:`sample_table`'s rows."""
    from inbetween_jax.evaluation.tables import flat_rows
    shown = [{"frames": r["frames"], "windows": r["windows"],
              "mean-of-N L2P / interp": r["mean_l2p"] / r["interp_l2p"], "best-of-N / interp": r["best_l2p"] /
              r["interp_l2p"], "APD (m)": r["apd_m"], "pairwise (cm)": r["pairwise_cm"],
              "score / ground truth's": r["score"] / max(r["score_gt"], 1e-9)} for r in table_rows]
    flat = flat_rows([dict(r, **s) for r, s in zip(table_rows, shown)], table="samples", data=data,
                     model="interaction", variant=variant, keys=("frames",))
    lines = [f"**Samples** ({variant}; N = 10 per window, true gap; sample 0 is the deterministic fill)", "",
             "| " + " | ".join(shown[0]) + " |", "|" + "---|" * len(shown[0])] if shown else []
    lines += ["| " + " | ".join(f"{v:.3f}" if isinstance(v, float) else str(v) for v in s.values()) + " |"
              for s in shown]
    return flat, "\n".join(lines)
