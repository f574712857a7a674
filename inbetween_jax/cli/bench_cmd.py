"""``inbetween bench``: in-betweening tables on LaFAN1 ($LAFAN1_DIR / --source) or the embedded CMU default.

Writes ``<results>/bench.md`` and ``<results>/bench.json`` (with ``rows``: one record per number of bench.md:
``table``, ``data``, ``model``, ``variant``, ``frames`` or ``gap_s``, ``metric``, ``value``):
1. the official LaFAN1 baseline table (zero-velocity / interpolation; L2Q, L2P, NPSS at 5/15/30/45, 10 past
   frames);
2. the S-CVAE paper's Table 1 layout (APD L2P L2Q ADE SLDE NPSS FootSlide at 10/30/50, one past keyframe);
3. each registered model's own tables, from the run folder ``<runs>/<model>`` (and ``<runs>/<model>_<name>``
   folders: the same model with another preset, e.g. ``scvae_cpu`` beside ``scvae``); a model without a run is
   evaluated with the weights shipped in the package when they fit the source's skeleton (CMU-trained: the
   embedded / CMU sources, not LaFAN1), its rows marked ``"weights": "shipped"``; otherwise it is listed as skipped.
L2P statistics: computed from the source's training windows, or read from ``--l2p-stats FILE.npz``
(``x_mean``, ``x_std`` of shape (1, J*3, 1), e.g. the official LaFAN1 ``train_stats``).
Each section is announced on stderr while it runs.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import time

from inbetween_jax.errors import NPZ_READ_ERRORS, UserError
from inbetween_jax.models import MODELS, REGISTRY


def add_parser(sub) -> None:
    p = sub.add_parser("bench", help="benchmark tables: baselines and every trained model",
                       description=__doc__.split("\n\n")[0].split(": ", 1)[1], epilog=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--source", default=None,
                   help="LaFAN1 or BVH folder, 'embedded' or 'cmu' (default: $LAFAN1_DIR, else the embedded CMU clips)")
    p.add_argument("--results", default="results", help="output folder for bench.md / bench.json (default results)")
    p.add_argument("--runs", default="runs", help="folder holding one run folder per model (default runs)")
    p.add_argument("--models", default=",".join(MODELS), help=f"comma-separated models (default {','.join(MODELS)})")
    p.add_argument("--l2p-stats", default=None, metavar="FILE.npz", help="L2P statistics (x_mean, x_std)")
    p.add_argument("--quick", action="store_true", help="fewer samples in the model sections")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    p.set_defaults(run=run)


def say(msg: str) -> None:
    print(f"bench: {msg}", file=sys.stderr, flush=True)


def load_l2p_stats(source, path):
    import numpy as np

    from inbetween_jax.data import l2p_stats, load_dataset
    if path:
        try:
            with np.load(path, allow_pickle=False) as z:
                return np.asarray(z["x_mean"]), np.asarray(z["x_std"]), f"from {os.path.basename(path)}"
        except (*NPZ_READ_ERRORS, KeyError) as e:
            raise UserError(f"--l2p-stats {path}: not readable L2P statistics, needs arrays x_mean and x_std "
                            f"({type(e).__name__}: {str(e)[:120]})") from None
    _, gp = load_dataset(source, "train").global_pose()
    x_mean, x_std = l2p_stats(gp)
    return x_mean, x_std, "computed on this source's training windows"


def _check(args) -> list:
    models = [m for m in args.models.split(",") if m]
    for m in models:
        if m not in REGISTRY:
            raise UserError(f"--models: unknown model {m!r} (choose {', '.join(MODELS)})")
    if args.source not in (None, "embedded", "cmu") and not os.path.isdir(args.source):
        raise UserError(f"--source {args.source}: no such folder")
    if args.l2p_stats and not os.path.isfile(args.l2p_stats):
        raise UserError(f"--l2p-stats {args.l2p_stats}: no such file")
    if os.path.exists(args.results) and not os.path.isdir(args.results):
        raise UserError(f"--results {args.results}: exists and is not a folder")
    return models


def data_label(src) -> str | None:
    """A data source as shown in the tables: a named source as it is, a folder by its name only (a run.json may
    record the trainer's machine-specific path)."""
    return src if not src or src in ("embedded", "cmu") else os.path.basename(os.path.normpath(str(src)))


def why_not_run(run_dir: str) -> str | None:
    """Why ``run_dir`` is not benchmarked as a run, in the section's words: ``"no run in"`` (missing),
    ``"no checkpoint yet in"`` (a run folder whose training stopped before its first checkpoint); else None."""
    if not os.path.exists(run_dir):
        return "no run in"
    from inbetween_jax.train.run import RunError, load_run
    try:
        return "no checkpoint yet in" if load_run(run_dir, need_checkpoint=False).step is None else None
    except RunError:
        return None                                  # not a run folder: its benchmark says why in one line


def shipped_section(model: str, run_dir: str, source: str, data: str, skeleton, args,
                    why: str = "no run in") -> dict | None:
    """``model``'s section from its shipped weights (the model's own rows marked ``weights: shipped``), a skip line
    saying why they do not apply, or None when no weights ship for it; ``why``: why the run folder is not used."""
    from inbetween_jax.data import Skeleton
    from inbetween_jax.shipped import shipped_dir, shipped_run
    from inbetween_jax.train.run import RunError
    folder = shipped_dir(model)
    if folder is None:
        return None
    skip = f"**{model}**: skipped, {why} `{run_dir}`"
    try:
        run_ = shipped_run(model)
    except RunError as err:
        return {"markdown": f"{skip}; the shipped weights are unusable ({err}).", "rows": []}
    trained_on = data_label(run_.shipped.get("data_source")) or "CMU mocap"
    if data == "lafan1":
        return {"markdown": f"{skip}; the shipped {model} weights were trained on CMU mocap ({trained_on}) and do not "
                            f"apply to LaFAN1 (train one with `inbetween train {model}`).", "rows": []}
    skel = Skeleton.from_dict(run_.skeleton) if run_.skeleton else None
    pairs = model == "interaction" and has_real_pairs(source)   # its bench reads the pairs (unused joints dropped)
    if not pairs and (skel is None or not skel.same_topology(skeleton)):
        return {"markdown": f"{skip}; the shipped {model} weights ({skel.num_joints if skel else '?'} joints) do not fit "
                            f"this source's {skeleton.num_joints}-joint skeleton.", "rows": []}
    say(f"{model}: {why} {run_dir}, evaluating the shipped weights ({folder}, step {run_.step})")
    try:
        out = REGISTRY[model].benchmark(source, args.results, folder, args.quick)
    except (OSError, ValueError) as err:
        return {"markdown": f"{skip}; shipped weights: {err}", "rows": []}
    for row in out.get("rows", []):
        if row.get("model") in (model, "bank"):      # not the baselines, ground truth or paper rows beside them
            row["weights"] = "shipped"
    out["weights"] = {"shipped": folder, "step": run_.step, "trained_on": trained_on}
    out["markdown"] = (f"**{model}: shipped weights** (step {run_.step}, trained on {trained_on}; {why} "
                       f"`{run_dir}`)\n\n{out.get('markdown', '')}")
    return out


def variant_run_dirs(runs: str, model: str) -> list:
    """Run folders ``<runs>/<model>_<name>`` (the same model trained with another preset or budget)."""
    if not os.path.isdir(runs):
        return []
    return [os.path.join(runs, d) for d in sorted(os.listdir(runs))
            if d.startswith(model + "_") and os.path.isfile(os.path.join(runs, d, "run.json"))]


def has_real_pairs(source) -> bool:
    from inbetween_jax.models.interaction.bench import has_real_pairs as has
    return has(source)


def run(args) -> int:
    models = _check(args)
    import jax

    from inbetween_jax.data import load_dataset, resolve_source
    from inbetween_jax.data.datasets import is_lafan1
    from inbetween_jax.evaluation import (TABLE_COLUMNS, baseline_table1, flat_rows, markdown_table,
                                          official_baseline_table)
    source = resolve_source(args.source)
    t0 = time.time()
    device = f"{jax.devices()[0].platform} ({jax.devices()[0].device_kind}, {jax.device_count()} device(s))"
    say(f"data: loading benchmark windows of {source}; running on {device}")
    bench = load_dataset(source, "benchmark")
    x_mean, x_std, stats_note = load_l2p_stats(source, args.l2p_stats)
    data = "lafan1" if is_lafan1(source) else "cmu-embedded" if source == "embedded" else "bvh-folder"
    label = {"lafan1": "LaFAN1", "cmu-embedded": "embedded CMU default", "bvh-folder": "BVH folder"}[data]
    header = (f"# In-betweening benchmark\n\nData: {label} (`{source}`), {len(bench)} benchmark windows of "
              f"{bench.window} frames, {bench.skeleton.num_joints} joints. L2P statistics {stats_note}.\n"
              f"Device: {device}. Generated {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC.\n")
    if data == "lafan1" and len(bench) != 2232:
        header += (f"\nNOTE: {len(bench)} of the official 2,232 benchmark windows are present: these are NOT the "
                   "official LaFAN1 figures (partial test set).\n")
    say("section 1: official LaFAN1 protocol, baselines")
    official = official_baseline_table(bench, x_mean, x_std)
    say("section 2: S-CVAE Table 1 layout, baselines")
    table1 = baseline_table1(bench, x_mean, x_std)
    sections = [header,
                markdown_table(official, ("L2Q", "L2P", "NPSS"), "Official LaFAN1 protocol: baselines, 10 past frames"),
                markdown_table(table1, TABLE_COLUMNS, "S-CVAE Table 1 layout (1 past keyframe)")]
    rows = flat_rows(official, "official", data) + flat_rows(table1, "table1", data)
    results = {"source": source, "device": device, "windows": len(bench), "official": official, "table1": table1,
               "models": {}}
    for i, model in enumerate(models):
        run_dir = os.path.join(args.runs, model)
        say(f"section {3 + i}: {model} (runs in {run_dir})")
        why = why_not_run(run_dir)                   # missing, or no checkpoint yet: the shipped weights if they fit
        shipped = None if why is None else shipped_section(model, run_dir, source, data, bench.skeleton, args, why)
        real_pairs = model == "interaction" and has_real_pairs(source)   # baselines table without a run
        if shipped is not None:
            out = shipped
        elif not os.path.exists(run_dir) and not real_pairs:
            out = {"markdown": f"**{model}**: skipped, no run in `{run_dir}` (train one with "
                               f"`inbetween train {model}`, or point `--runs` at a folder holding `{model}/`).",
                   "rows": []}
        else:
            try:
                out = REGISTRY[model].benchmark(source, args.results, run_dir if os.path.exists(run_dir) else None,
                                                args.quick)
            except (OSError, ValueError) as err:   # e.g. a run trained on another skeleton
                out = {"markdown": f"**{model}**: skipped, {err}", "rows": []}
        rows += out.get("rows", [])
        results["models"][model] = {k: v for k, v in out.items() if k not in ("markdown", "rows")}
        sections.append(out.get("markdown", ""))
        for extra in variant_run_dirs(args.runs, model):   # e.g. runs/scvae_cpu: the same model, another preset
            say(f"section {3 + i}: {model} (variant run {extra})")
            try:
                out = REGISTRY[model].benchmark(source, args.results, extra, args.quick)
            except (OSError, ValueError) as err:
                out = {"markdown": f"**{model}** (`{extra}`): skipped, {err}", "rows": []}
            rows += out.get("rows", [])
            results["models"][os.path.basename(extra)] = {k: v for k, v in out.items() if k not in ("markdown", "rows")}
            sections.append(out.get("markdown", ""))
    sections.append(f"Benchmark wall time: {time.time() - t0:.1f} s.")
    results["rows"] = rows
    from inbetween_jax.evaluation.figures import figures_markdown, worst_case_figures
    sections.append(figures_markdown(rows, args.results))         # one PNG per data set, beside bench.md
    from inbetween_jax.shipped import shipped_dir
    calibrations = {m: os.path.join(d, "ood_calibration.json") for m in models if (d := shipped_dir(m))}
    sections.append(worst_case_figures(rows, args.results, calibrations))   # per-window ratios; gate calibration
    text = "\n\n".join(s for s in sections if s) + "\n"
    os.makedirs(args.results, exist_ok=True)
    with open(os.path.join(args.results, "bench.md"), "w") as fh:
        fh.write(text)
    with open(os.path.join(args.results, "bench.json"), "w") as fh:
        json.dump(results, fh, indent=1, default=float)
    print(text)
    say(f"wrote {os.path.join(args.results, 'bench.md')} and bench.json ({len(rows)} rows)")
    return 0
