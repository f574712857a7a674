"""S-CVAE rows of the paper's Table 1 layout (plus MMPE) on the benchmark windows.

``run(source, results_dir, ckpt_dir, quick)``: keyframes at frame 9 (one past frame) and 9 + L + 1 for
L = 10, 30, 50; APD over 10 samples; accuracy metrics averaged over the samples.  Without a checkpoint a
tiny model is trained for a few steps only and its rows are labelled *untrained*.
Also writes ``<results>/scvae_error_over_time.png``: the per-frame joint position error along the longest
transition (mean over windows and samples, band = min..max over the samples averaged over windows) with
Slerp dashed, as Fig. 6 of the S-CVAE paper.
Also runnable: ``python experiments/bench_scvae.py [--source DIR] [--ckpt runs/scvae] [--results DIR] [--quick]``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

N_PAST = 10
LENGTHS = (10, 30, 50)


def run(source: str | None, results_dir: str, ckpt_dir: str | None, quick: bool) -> dict:
    from inbetween_jax import metrics
    from inbetween_jax.data import l2p_stats, load_dataset, resolve_source
    from inbetween_jax.evaluation import TABLE_COLUMNS, baseline_table1, markdown_table, transition_metrics
    from inbetween_jax.models import scvae_eval

    t0 = time.time()
    source = resolve_source(source)
    train = load_dataset(source, "train")
    bench = load_dataset(source, "benchmark")
    x_mean, x_std = l2p_stats(train.global_pose()[1])
    num_samples = 10
    note = ""
    if quick:
        bench = bench.take(slice(0, 64))
        note = f"quick: first {len(bench)} benchmark windows. "
    info = scvae_eval.run_info(ckpt_dir) if ckpt_dir else {}
    joints = int(train.local_quats.shape[2])
    if info.get("num_joints", joints) != joints:
        md = (f"**S-CVAE**: skipped, the checkpoint in `{ckpt_dir}` was trained on a {info['num_joints']}-joint "
              f"skeleton ({info.get('source')}) and this source has {joints} joints.")
        return {"rows": [], "markdown": md, "step": None, "source": source, "windows": len(bench)}
    if ckpt_dir and os.path.isdir(scvae_eval.find_checkpoints(ckpt_dir)):
        cfg, state, step = scvae_eval.load_run(ckpt_dir, train)
        label = "S-CVAE"
        note += f"checkpoint `{ckpt_dir}` at step {step}. "
    else:
        cfg, state, step = _untrained(train)
        label = "S-CVAE (untrained)"
        note += f"NO checkpoint: a tiny model trained for {step} steps only -- the rows are meaningless. "
    rows = [r for r in baseline_table1(bench, x_mean, x_std, LENGTHS, N_PAST) if r["method"] == "Slerp"]
    for length in LENGTHS:
        s = scvae_eval.sample_transitions(cfg.model, state, bench, N_PAST, length, num_samples)
        if length == max(LENGTHS):
            longest = s
        row = {"method": label, "frames": length,
               **transition_metrics(bench, N_PAST, length, s["q"], s["r"], x_mean, x_std)}
        row["MMPE"] = (float(metrics.mmpe(s["mid_f"][:, :, None], s["mid_b"][:, :, None], mid_index=0))
                       if "mid_f" in s else None)
        rows.append(row)
    rows.sort(key=lambda r: (r["frames"], r["method"] != "Slerp"))
    cols = tuple(TABLE_COLUMNS) + ("MMPE",)
    md = markdown_table(rows, cols, f"S-CVAE, Table 1 layout ({len(bench)} windows, {num_samples} samples)")
    os.makedirs(results_dir, exist_ok=True)
    plot = error_over_time_plot(bench, max(LENGTHS), longest, label,
                                os.path.join(results_dir, "scvae_error_over_time.png"))
    md += (f"\n\n{note}APD/ADE/SLDE in m, FootSlide in cm/frame, MMPE in cm. Error along the {max(LENGTHS)}-frame "
           f"transition: `{os.path.basename(plot)}`. Wall {time.time() - t0:.0f} s.")
    out = {"rows": rows, "markdown": md, "step": step, "source": source, "windows": len(bench), "plots": [plot]}
    with open(os.path.join(results_dir, "scvae.json"), "w") as f:
        json.dump(out, f, indent=1)
    with open(os.path.join(results_dir, "scvae.md"), "w") as f:
        f.write(md + "\n")
    return out


def per_frame_error(windows, n_past: int, n_trans: int, q, r) -> np.ndarray:
    """Mean joint position error (data units, cm) of every transition frame against the ground truth.

    q: (S, B, n_trans, J, 4) local quaternions, r: (S, B, n_trans, 3) root positions of S samples of the
    transition after frame ``n_past - 1`` of the B windows.  Returns (S, B, n_trans).
    """
    from inbetween_jax.geometry import forward_kinematics, local_positions

    def fk(quats, root):
        lp = local_positions(np.asarray(root, np.float64), windows.skeleton.offsets)
        return forward_kinematics(np.asarray(quats, np.float64), lp, windows.parents)[1]

    lo, hi = n_past, n_past + n_trans
    gt = fk(windows.local_quats[:, lo:hi], windows.root_pos[:, lo:hi])                # (B, L, J, 3)
    return np.stack([np.linalg.norm(fk(qs, rs) - gt, axis=-1).mean(-1) for qs, rs in zip(q, r)])


def error_over_time_plot(windows, n_trans: int, samples: dict, label: str, path: str) -> str:
    """Plot the per-frame error of ``samples`` (``sample_transitions`` output) with Slerp as the baseline.

    Curve: mean over windows and samples; band: per window min..max over the samples, averaged over windows.
    """
    from inbetween_jax.baselines import interpolate_transition
    from inbetween_jax.viz import plot_error_over_time
    err = per_frame_error(windows, N_PAST, n_trans, samples["q"], samples["r"])           # (S, B, L)
    q, r = interpolate_transition(windows.local_quats.astype(np.float64), windows.root_pos.astype(np.float64),
                                  N_PAST, n_trans)
    slerp = per_frame_error(windows, N_PAST, n_trans, q[None], r[None])[0].mean(0)
    title = (f"{n_trans}-frame transitions, {err.shape[1]} windows\n"
             f"band: min..max over {err.shape[0]} samples, averaged over windows")
    return plot_error_over_time(np.arange(1, n_trans + 1), err.mean((0, 1)), err.min(0).mean(0),
                                err.max(0).mean(0), path, label, baseline={"Slerp": slerp},
                                ylabel="mean joint position error (cm)", title=title)


def _untrained(train, steps: int = 3):
    """A tiny S-CVAE trained for ``steps`` steps in a temporary folder (smoke test of the pipeline)."""
    from inbetween_jax.configs.scvae import get_config
    from inbetween_jax.models import scvae_train
    from inbetween_jax.train import apply_overrides
    cfg = apply_overrides(get_config("tiny"), ["train.trans_max=20", f"train.ckpt_every={steps}"])
    with tempfile.TemporaryDirectory() as tmp:
        state, _ = scvae_train.train(cfg, train, tmp, num_steps=steps, progress=False)
    return cfg, state, steps


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", default=None)
    ap.add_argument("--ckpt", default=os.path.join("runs", "scvae"))
    ap.add_argument("--results", default="results")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    out = run(args.source, args.results, args.ckpt, args.quick)
    print(out["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
