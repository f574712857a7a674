"""CAE benchmark: the paper's Table 1 (reconstruction / 60 / 120-frame gaps) and Table 2 (de-noising) for
linear interpolation, the Holden-style 1D-conv AE, the Vanilla AE and the CAE, plus bone-length spread.

``python experiments/bench_cae.py [--source DIR] [--results DIR] [--ckpt DIR] [--quick]``

``--ckpt`` is a run folder of ``experiments/train_cae.py`` or a folder holding several (one per variant,
recognised by the variant in their ``cae_meta.json``).  Without checkpoints, small models are trained
briefly (``quick``: a few steps) and every row says so.

Protocol.  Test clips: the test split's motions cut in 240-frame windows at stride 120.  Errors are the
root-aligned 3D joint errors (cm) of the body-frame joint positions (the representation's position rows:
root projected on the floor, facing +Z), mean and std over every (frame, joint) scored --
``metrics.mpjpe(root_relative=False)``.  Table 1: one gap centred in the clip, scored over the gap frames
(0 frames: the clean clip is reconstructed and every frame is scored).  Table 2: N(0, sigma^2) noise on
the position rows in normalised units, or each joint of each frame dropped with probability p; every frame
is scored.  Noise and dropout draws are identical for every method.
"""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GAPS = (0, 60, 120)
SIGMAS = (1.0, 1.5)
PS = (0.3, 0.5)
LABELS = {"linear": "Linear interpolation", "holden1d": "Holden-style 1D conv AE (60)",
          "vanilla": "Vanilla AE (60)", "cae": "CAE (ours)"}
PAPER_T1 = {"linear": ("n/a", "10.45 (± 15.5)", "17.04 (± 24.4)"), "holden1d": ("4.44 (± 6.5)", "15.28 (± 19.1)",
            "18.26 (± 24.5)"), "vanilla": ("2.79 (± 6.7)", "7.45 (± 11.7)", "13.61 (± 21.6)"),
            "cae": ("2.75 (± 5.2)", "5.47 (± 8.6)", "7.00 (± 10.6)")}


def _find_runs(ckpt_dir):
    """{variant: run_dir} from a run folder or a folder of run folders."""
    from inbetween_jax.models.cae_train import META_FILE
    runs = {}
    cands = [ckpt_dir] + [os.path.join(ckpt_dir, d) for d in sorted(os.listdir(ckpt_dir))]
    for d in cands:
        meta = os.path.join(d, META_FILE)
        if os.path.isfile(meta):
            with open(meta) as fh:
                runs.setdefault(json.load(fh)["config"]["model"]["variant"], d)
    return runs


def _train_short(source, results_dir, quick):
    from inbetween_jax.models.cae_train import train
    steps = 3 if quick else 150
    runs = {}
    for variant in ("holden1d", "vanilla", "cae"):
        run_dir = os.path.join(results_dir, "cae_bench_runs", f"{variant}-{steps}")
        extra = [] if variant == "cae" else ["mask.curriculum=false", "mask.fixed_mu=60"]
        train(run_dir, source, "tiny", [f"model.variant={variant}", "data.max_motions=0",
                                        "batch_size=8", f"num_steps={steps}", "steps_per_epoch=10", *extra],
              progress=False)
        runs[variant] = run_dir
    return runs, f"UNTRAINED / short training ({steps} steps, tiny widths) -- not the paper's models"


def _clips(motions, normalizer, length=240, stride=120, limit=None):
    from inbetween_jax.models.cae_data import motion_features
    out = []
    for m in motions:
        f = normalizer(motion_features(m).features)
        for s in range(0, f.shape[0] - length + 1, stride):
            out.append(f[s:s + length].T)
    x = np.stack(out).astype(np.float32)
    return x[:limit] if limit else x


def _stats(pred, target, normalizer, j, frames=None):
    from inbetween_jax.metrics import mpjpe
    from inbetween_jax.models.cae_data import split_features
    p = split_features(normalizer.inverse(np.swapaxes(pred, 1, 2)), j)[0]
    g = split_features(normalizer.inverse(np.swapaxes(target, 1, 2)), j)[0]
    mean, std = mpjpe(p, g, mask=frames, root_relative=False)
    return float(mean), float(std)


def _fmt(ms):
    return "n/a" if ms is None else f"{ms[0]:.2f} (± {ms[1]:.1f})"


def run(source: str | None, results_dir: str, ckpt_dir: str | None, quick: bool) -> dict:
    """Evaluate and write ``cae_bench.json`` / ``cae_bench.md`` under ``results_dir``; returns the dict."""
    from inbetween_jax.data import load_motions, resolve_source
    from inbetween_jax.models import cae_infer as ci
    from inbetween_jax.models.cae_train import load_trained

    t0 = time.time()
    src = resolve_source(source)
    os.makedirs(results_dir, exist_ok=True)
    if ckpt_dir and _find_runs(ckpt_dir):
        runs, note = _find_runs(ckpt_dir), "trained checkpoints"
    else:
        runs, note = _train_short(src, results_dir, quick)
    models = {v: load_trained(d) for v, d in runs.items()}
    ref = models.get("cae") or next(iter(models.values()))
    norm, j = ref.normalizer, ref.num_joints
    motions = load_motions(src, "test")
    for v, m in models.items():
        if not motions[0].skeleton.same_topology(m.skeleton):
            raise ValueError(f"checkpoint {runs[v]} was trained on another skeleton ({m.skeleton.num_joints} joints) "
                             f"than {src} ({motions[0].skeleton.num_joints} joints); pass the matching --source")
    x = _clips(motions, norm, limit=8 if quick else None)
    n, d, t = x.shape
    rng = np.random.default_rng(0)
    corrupt = {f"sigma={s}": (ci.add_position_noise(rng, x, j, s), np.ones_like(x)) for s in SIGMAS}
    for p in PS:
        corrupt[f"p={p}"] = (x, ci.dropout_mask(rng, (n, t), j, p))
    methods = ["linear"] + [v for v in ("holden1d", "vanilla", "cae") if v in models]
    table1, table1s, table2, bones = {}, {}, {}, {}
    parents = ref.skeleton.parents
    gt_bones = ci.bone_length_stats(x, norm, j, parents)
    for meth in methods:
        def predict(inp, mask):
            if meth == "linear":
                return ci.linear_fill(inp, mask)
            return ci.fill(models[meth], inp, mask)
        row, row_s = [], []
        for gaps, out in ((GAPS, row), ((0, 30, 60), row_s)):
            for g in gaps:
                if g == 0:
                    out.append(None if meth == "linear" else _stats(predict(x, np.ones_like(x)), x, norm, j))
                    continue
                a = (t - g) // 2
                fm = np.broadcast_to(ci.gap_frames(t, [(a, a + g)]), (n, t))
                out.append(_stats(predict(x, ci.frame_mask_image(fm, j)), x, norm, j, frames=1.0 - fm))
        table1[meth], table1s[meth] = row, row_s
        table2[meth] = {k: _stats(predict(inp * 1.0, m) if meth != "linear" or k.startswith("p")
                                  else inp, x, norm, j) for k, (inp, m) in corrupt.items()}
        if meth != "linear":
            pb = ci.bone_length_stats(predict(x, np.ones_like(x)), norm, j, parents)
            bones[meth] = {"mean_abs_median_dev_cm": float(np.mean(np.abs(np.median(pb, 0) - np.median(gt_bones, 0)))),
                           "mean_std_cm": float(np.mean(pb.std(0))), "gt_mean_std_cm": float(np.mean(gt_bones.std(0))),
                           "mean_iqr_cm": float(np.mean(np.subtract(*np.percentile(pb, [75, 25], 0))))}
    result = {"source": src, "note": note, "runs": runs, "num_clips": n, "clip_length": t,
              "fps": float(motions[0].fps), "test_files": [os.path.basename(m.source) for m in motions],
              "steps": {v: m.step for v, m in models.items()}, "table1": table1, "table1_seconds": table1s,
              "table2": table2, "bones": bones, "wall_s": time.time() - t0}
    with open(os.path.join(results_dir, "cae_bench.json"), "w") as fh:
        json.dump(result, fh, indent=1)
    md = _markdown(result, methods)
    with open(os.path.join(results_dir, "cae_bench.md"), "w") as fh:
        fh.write(md)
    print(md)
    return result


def _markdown(r, methods):
    lines = [f"CAE benchmark -- {r['note']}; data: {r['source']} test split ({', '.join(r['test_files'])}), "
             f"{r['num_clips']} clips of {r['clip_length']} frames at {r['fps']:.0f} Hz; 3D joint error in cm, "
             "mean (± std), root-aligned.", "",
             "Table 1 (gap in frames; scored over the gap)", "",
             "| Model | 0 Frames | 60 Frames | 120 Frames | paper 0 / 60 / 120 |", "|---|---|---|---|---|"]
    for m in methods:
        lines.append(f"| {LABELS[m]} | " + " | ".join(_fmt(v) for v in r["table1"][m]) + " | "
                     + " / ".join(PAPER_T1[m]) + " |")
    lines += ["", f"Table 1b (same durations as the paper's 60 Hz gaps: 30 / 60 frames at {r['fps']:.0f} Hz = 1 s / 2 s)",
              "", "| Model | 0 Frames | 30 Frames | 60 Frames |", "|---|---|---|---|"]
    for m in methods:
        lines.append(f"| {LABELS[m]} | " + " | ".join(_fmt(v) for v in r["table1_seconds"][m]) + " |")
    keys = [f"sigma={s}" for s in SIGMAS] + [f"p={p}" for p in PS]
    lines += ["", "Table 2 (de-noising; every frame scored; sigma in normalised units; linear row for sigma: the "
              "noisy input itself)", "", "| Model | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for m in methods:
        lines.append(f"| {LABELS[m]} | " + " | ".join(_fmt(r["table2"][m][k]) for k in keys) + " |")
    lines += ["", "Bone lengths on reconstruction (cm): mean over bones", "",
              "| Model | median - GT median | std | IQR | GT std |", "|---|---|---|---|---|"]
    for m, b in r["bones"].items():
        lines.append(f"| {LABELS[m]} | {b['mean_abs_median_dev_cm']:.2f} | {b['mean_std_cm']:.2f} | "
                     f"{b['mean_iqr_cm']:.2f} | {b['gt_mean_std_cm']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv):
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", default=None)
    ap.add_argument("--results", default="results")
    ap.add_argument("--ckpt", default=None)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    run(a.source, a.results, a.ckpt, a.quick)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    sys.exit(main(sys.argv[1:]))
