"""``make bench``: in-betweening tables on LaFAN1 ($LAFAN1_DIR / --source) or the embedded CMU default.

Writes ``<results>/bench.md`` and ``<results>/bench.json``:
1. the official LaFAN1 baseline table (zero-velocity / interpolation; L2Q, L2P, NPSS at 5/15/30/45,
   10 past frames);
2. the S-CVAE paper's Table 1 layout (APD L2P L2Q ADE SLDE NPSS FootSlide at 10/30/50, one past keyframe);
3. each model's own tables when ``experiments/bench_<model>.py`` exists and a checkpoint is found in
   ``runs/<model>`` (or ``--ckpt-root``); models without a checkpoint are listed as skipped;
4. the speed section (``experiments/bench_speed.py``: JAX against PyTorch eager, inference, compile times;
   ``--no-speed`` skips it).

L2P statistics: computed from the source's training windows, or read from ``--l2p-stats FILE.npz``
(``x_mean``, ``x_std`` of shape (1, J*3, 1), e.g. the official LaFAN1 ``train_stats``).
"""
import argparse
import datetime
import importlib
import json
import os
import sys
import time

import numpy as np

from inbetween_jax.data import l2p_stats, load_dataset, resolve_source
from inbetween_jax.data.datasets import is_lafan1
from inbetween_jax.evaluation import TABLE_COLUMNS, baseline_table1, markdown_table, official_baseline_table

MODELS = ("scvae", "cae", "interaction")


def load_l2p_stats(source, path):
    if path:
        if not os.path.exists(path):
            raise SystemExit(f"error: --l2p-stats file {path!r} not found")
        z = np.load(path)
        return z["x_mean"], z["x_std"], f"from {os.path.basename(path)}"
    _, gp = load_dataset(source, "train").global_pose()
    x_mean, x_std = l2p_stats(gp)
    return x_mean, x_std, "computed on this source's training windows"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", default=None, help="LaFAN1 or BVH folder; default $LAFAN1_DIR or embedded")
    ap.add_argument("--results", default="results")
    ap.add_argument("--l2p-stats", default=None)
    ap.add_argument("--ckpt-root", default="runs")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--quick", action="store_true", help="passed to the model benches (fewer samples)")
    ap.add_argument("--no-speed", action="store_true", help="skip the speed section (JAX vs PyTorch eager timings)")
    ap.add_argument("--speed-reps", type=int, default=5, help="timed calls per speed row (medians)")
    args = ap.parse_args(argv)
    source = resolve_source(args.source)
    t0 = time.time()
    bench = load_dataset(source, "benchmark")
    x_mean, x_std, stats_note = load_l2p_stats(source, args.l2p_stats)
    label = ("LaFAN1" if is_lafan1(source) else "embedded CMU default" if source == "embedded" else "BVH folder")
    header = (f"# In-betweening benchmark\n\nData: {label} (`{source}`), {len(bench)} benchmark windows of "
              f"{bench.window} frames, {bench.skeleton.num_joints} joints. L2P statistics {stats_note}.\n"
              f"Generated {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC.\n")
    if is_lafan1(source) and len(bench) != 2232:
        header += (f"\nNOTE: {len(bench)} of the official 2,232 benchmark windows are present: these are NOT the "
                   "official LaFAN1 figures (partial test set).\n")
    official = official_baseline_table(bench, x_mean, x_std)
    table1 = baseline_table1(bench, x_mean, x_std)
    sections = [header,
                markdown_table(official, ("L2Q", "L2P", "NPSS"),
                               "Official LaFAN1 protocol: baselines, 10 past frames"),
                markdown_table(table1, TABLE_COLUMNS, "S-CVAE Table 1 layout (1 past keyframe)")]
    results = {"source": source, "windows": len(bench), "official": official, "table1": table1, "models": {}}
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    for model in [m for m in args.models.split(",") if m]:
        ckpt = os.path.join(args.ckpt_root, model)  # runs/cae holds one run folder per CAE variant
        if not os.path.exists(os.path.join(os.path.dirname(__file__), f"bench_{model}.py")):
            continue
        if not os.path.isdir(ckpt):
            sections.append(f"**{model}**: skipped, no checkpoint in `{ckpt}` (run `make train MODEL={model}`).")
            continue
        try:
            out = importlib.import_module(f"bench_{model}").run(source, args.results, ckpt, args.quick)
        except (OSError, ValueError) as err:  # e.g. a checkpoint trained on another skeleton
            sections.append(f"**{model}**: skipped, {err}")
            continue
        results["models"][model] = out
        sections.append(out.get("markdown", "") if isinstance(out, dict) else str(out))
    if not args.no_speed:   # last, in this process: compiled JAX against PyTorch eager (bench_speed.py)
        speed = importlib.import_module("bench_speed").run(source, args.results, args.speed_reps, args.quick)
        results["speed"] = {k: v for k, v in speed.items() if k != "markdown"}
        sections.append(speed["markdown"])
    sections.append(f"Benchmark wall time: {time.time() - t0:.1f} s.")
    text = "\n\n".join(s for s in sections if s) + "\n"
    os.makedirs(args.results, exist_ok=True)
    with open(os.path.join(args.results, "bench.md"), "w") as fh:
        fh.write(text)
    with open(os.path.join(args.results, "bench.json"), "w") as fh:
        json.dump(results, fh, indent=1, default=float)
    print(text)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except (OSError, ValueError) as err:  # BVHError is a ValueError: one line naming file and problem
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
