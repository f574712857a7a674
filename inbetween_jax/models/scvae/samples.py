"""The S-CVAE as a generative model: N samples of the same keyframes scored together
(:func:`inbetween_jax.evaluation.samples.sample_metrics`) beside Slerp, on any windows.

The bench writes these rows for the test windows (``table: "samples"`` in bench.json); ``python
experiments/scvae_samples.py RUN_DIR`` writes them for the validation subjects of the run's training split,
where variants are chosen.
"""
from __future__ import annotations

import numpy as np

__all__ = ["NUM_SAMPLES", "COLUMNS", "RATIO_COLUMNS", "samples_rows", "length_rows", "validation_rows"]

NUM_SAMPLES = 10
COLUMNS = ("APD", "pairwise_cm", "mean_L2P", "best_L2P", "mean_cm", "best_cm", "reach", "reach_truth",
           "foot_slide_mean", "foot_slide_worst", "steps", "steps_truth")
RATIO_COLUMNS = ("ratio_mean", "ratio_best", "pairwise_over_slerp")


def samples_rows(trained, windows, lengths, n_past: int, x_mean, x_std, name: str, num_samples: int = NUM_SAMPLES,
                 seed: int = 0) -> list:
    """Rows ``{"method", "frames", *COLUMNS}``: Slerp, the network's samples before the out-of-distribution
    gate and, for a gated model, after it; with ``model.bank_sample_weight`` (and a bank) also the sampled mode
    (``", sampled mode"``: sample s >= 1 moved toward the bank's s-th nearest transition, after the gate).
    ``ratio_best`` / ``ratio_mean``: best- / mean-of-N joint error over Slerp's; ``pairwise_over_slerp``: how far
    apart the samples are, over Slerp's error."""
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.bank import sampled_mode
    from inbetween_jax.models.scvae.gate import gate_windows
    model_cfg = trained.cfg.model
    gated = trained.gate is not None and model_cfg.ood_gate
    fa = tuple(trained.extra.get("forward_axis") or windows.skeleton.forward_axis())
    rows = []
    for n in lengths:
        s = infer.sample_transitions(model_cfg, trained.state, windows, n_past, n, num_samples, seed=seed,
                                     bank=trained.bank, sampled=False)
        variants, weight = [(f"{name}, no gate" if gated else name, s["q"], s["r"])], None
        if gated:
            q, r, _, weight = gate_windows(trained.gate, windows, n_past - 1, n_past + n, s["q"], s["r"], fa)
            variants.append((name, q, r))
        if trained.bank is not None and sampled_mode(model_cfg, num_samples):   # the sampled mode, after the gate
            variants.append((f"{name}, sampled mode", *infer.bank_samples(trained.bank, model_cfg, windows, n_past,
                                                                          n, *variants[-1][1:], weight)))
        rows += length_rows(windows, n_past, n, x_mean, x_std, variants)
    return rows


def length_rows(windows, n_past: int, n: int, x_mean, x_std, variants) -> list:
    """Slerp's row and one per ``(method, q (S, B, n, J, 4), r (S, B, n, 3))`` of ``variants`` for the
    ``n``-frame transitions of ``windows`` (see :func:`samples_rows`)."""
    from inbetween_jax.baselines import interpolate_transition
    from inbetween_jax.evaluation.samples import sample_metrics
    sq, sr = interpolate_transition(windows.local_quats.astype(np.float64), windows.root_pos.astype(np.float64),
                                    n_past, n)
    slerp = sample_metrics(windows, n_past, n, sq, sr, x_mean, x_std)
    rows = [{"method": "Slerp", "frames": n, **slerp}]
    for method, q, r in variants:
        m = sample_metrics(windows, n_past, n, q, r, x_mean, x_std)
        rows.append({"method": method, "frames": n, **m, "ratio_mean": m["mean_cm"] / slerp["mean_cm"],
                     "ratio_best": m["best_cm"] / slerp["mean_cm"],
                     "pairwise_over_slerp": m["pairwise_cm"] / slerp["mean_cm"]})
    return rows


def validation_rows(run, source: str, lengths=(10, 30, 50), n_past: int = 10, num_samples: int = NUM_SAMPLES,
                    split: str | None = None) -> list:
    """:func:`samples_rows` on the validation split of the run's training data (``train.split=fit-subjects``:
    whole held-out subjects; ``split``: another held-out split, e.g. ``val-activities`` for a run trained on
    ``fit-activities``), 65-frame windows at offset 20, L2P statistics of those windows."""
    from inbetween_jax.data import l2p_stats, load_dataset
    from inbetween_jax.data.datasets import val_split_of
    from inbetween_jax.models.scvae import infer
    trained = infer.load(run)
    val = load_dataset(source, split or val_split_of(run.config.get("train", {}).get("split", "fit")),
                       window=n_past + max(lengths) + 5, offset=20)
    x_mean, x_std = l2p_stats(val.global_pose()[1])
    lengths = [n for n in lengths if n <= trained.cfg.data.trans_max]
    return samples_rows(trained, val, lengths, n_past, x_mean, x_std, f"S-CVAE ({run.preset})", num_samples)
