"""CAE benchmark: the paper's Table 1 (reconstruction / 60 / 120-frame gaps) and Table 2 (de-noising) for
linear interpolation, the Holden-style 1D-conv AE, the Vanilla AE and the CAE, plus bone-length spread, and
a time-matched table: reconstruction (no gap) and 1 s / 2 s / 4 s gaps (30 / 60 / 120 frames at 30 Hz), each
gap also as a ratio to linear fill.  The time-matched gap sits in the middle of each clip, so it is scored on as
many gaps as there are test clips (11 on the embedded CMU split); the same gaps are therefore also put at every
position (:func:`every_position`) and their ratio to linear fill given with a 95 % bootstrap interval over the
clips (:func:`ratio_interval`).  Two non-learned rows (``BASELINES``): linear fill (the paper's) and the
limited cubic Hermite fill (:func:`inbetween_jax.baselines.hermite_fill`, not in the paper), the pre-fill of
``model.fill=hermite`` runs, so the tables show how much of a residual model's number is its fill alone.

``run(source, results_dir, run_dir, quick)``: ``run_dir`` is a CAE run folder, a folder of run folders
(e.g. ``runs/cae`` holding ``cae/``, ``vanilla/``, ``holden1d/``) or both (a run folder whose sub-folders
are runs); every CAE run found is evaluated under a method key: ``model.variant``, plus ``_residual`` for
a run with ``model.residual`` (``cae_residual``: the ``improved`` preset); a second run of the same key (in
name order) is keyed ``KEY:FOLDER`` and labelled with its folder name, so runs that differ only in switches
share one table.  The protocol is :mod:`inbetween_jax.evaluation.infilling`;
``quick`` evaluates the first 8 test clips only.  Writes ``cae_bench.json`` / ``cae_bench.md`` under
``results_dir``.
"""
from __future__ import annotations

import functools
import json
import os
import time

import numpy as np

LABELS = {"linear": "Linear interpolation", "hermite": "Hermite fill (limited cubic; baseline, not in paper)",
          "holden1d": "Holden-style 1D conv AE (60)", "vanilla": "Vanilla AE (60)", "cae": "CAE (ours)",
          "holden1d_residual": "Holden-style 1D AE, residual", "vanilla_residual": "Vanilla AE, residual",
          "cae_residual": "CAE, residual (improved)"}
PAPER_T1 = {"linear": ("n/a", "10.45 (± 15.5)", "17.04 (± 24.4)"), "holden1d": ("4.44 (± 6.5)", "15.28 (± 19.1)",
            "18.26 (± 24.5)"), "vanilla": ("2.79 (± 6.7)", "7.45 (± 11.7)", "13.61 (± 21.6)"),
            "cae": ("2.75 (± 5.2)", "5.47 (± 8.6)", "7.00 (± 10.6)"), "hermite": ("-", "-", "-")}
BASELINES = ("linear", "hermite")   # non-learned rows: their fill functions (baselines.linear_fill / hermite_fill)
VARIANT_ORDER = ("holden1d", "vanilla", "cae", "holden1d_residual", "vanilla_residual", "cae_residual")
SECONDS = (1, 2, 4)   # time-matched gaps
POSITION_STRIDE = 10  # every-position table: frames between gap starts
POSITION_MARGIN = 10  # every-position table: known frames kept before and after the gap
BOOTSTRAP = 2000      # every-position table: resamples of the clips for the 95 % interval
TRAIN_HINT = "inbetween train cae --run-dir runs/cae [--preset cpu model.variant=vanilla|holden1d]"

__all__ = ["find_runs", "run", "val_score", "every_position", "ratio_interval", "in_table_units"]


def find_runs(run_dir: str | None) -> dict:
    """``{method key: Run}`` of the CAE runs (with a checkpoint) in ``run_dir`` or its sub-folders; the key
    is the run's ``model.variant``, with ``_residual`` appended when ``model.residual`` is on, and
    ``:FOLDER`` appended for every further run of a key already taken (folders in name order)."""
    from inbetween_jax.train.run import RunError, load_run
    if not run_dir or not os.path.isdir(run_dir):
        return {}
    runs = {}
    for d in [run_dir] + [os.path.join(run_dir, s) for s in sorted(os.listdir(run_dir))]:
        if not os.path.isfile(os.path.join(d, "run.json")):
            continue
        try:
            r = load_run(d)
        except RunError:
            continue
        if r.model == "cae":
            m = r.config.get("model", {})
            key = m.get("variant", "cae") + ("_residual" if m.get("residual") else "")
            runs[key if key not in runs else f"{key}:{os.path.basename(os.path.normpath(d))}"] = r
    return runs


def _label(method: str) -> str:
    """The table label of a method key (``KEY:FOLDER`` for a further run of ``KEY``)."""
    key, _, folder = method.partition(":")
    return LABELS[key] + (f" [{folder}]" if folder else "")


def _fmt(ms):
    return "n/a" if ms is None else f"{ms[0]:.2f} (± {ms[1]:.1f})"


def _data_name(src: str) -> str:
    from inbetween_jax.data.datasets import is_lafan1
    return "lafan1" if is_lafan1(src) else "embedded" if src == "embedded" else "bvh"


def run(source: str | None, results_dir: str, run_dir: str | None, quick: bool = False) -> dict:
    """Evaluate every CAE run of ``run_dir``; returns ``{"markdown", "rows", ...the tables}``."""
    from inbetween_jax.data import load_motions, resolve_source
    from inbetween_jax.evaluation import infilling as proto
    from inbetween_jax.evaluation.worst_case import worst_case_markdown
    from inbetween_jax.models.cae.infer import load

    runs = find_runs(run_dir)
    if not runs:
        why = "no run folder given" if not run_dir else f"no trained CAE run in {run_dir}"
        return {"markdown": f"CAE benchmark skipped: {why} (train one: `{TRAIN_HINT}`).\n", "rows": [],
                "skipped": why}
    t0 = time.time()
    src = resolve_source(source)
    models = {v: load(r) for v, r in runs.items()}
    ref = models.get("cae") or next(iter(models.values()))
    norm, j = ref.normalizer, ref.num_joints
    motions = load_motions(src, "test")
    for v, m in models.items():
        if not motions[0].skeleton.same_topology(m.skeleton):
            raise ValueError(f"checkpoint {runs[v].run_dir} was trained on another skeleton "
                             f"({m.skeleton.num_joints} joints) than {src} ({motions[0].skeleton.num_joints} "
                             "joints); pass the matching --source")
    x = proto.test_clips(motions, norm, limit=8 if quick else None)
    corrupt = proto.corruptions(x, j)
    methods = list(BASELINES) + sorted(models, key=lambda v: (VARIANT_ORDER.index(v.partition(":")[0]), v))
    predictors = {meth: _baseline(meth) if meth in BASELINES else in_table_units(models[meth], norm)
                  for meth in methods}
    tables = {}
    for meth in methods:
        tables[meth] = proto.evaluate_method(predictors[meth], x, corrupt, norm, j, ref.skeleton.parents,
                                             learned=meth not in BASELINES)
    fps = float(motions[0].fps)
    timed = {meth: _time_matched(predictors[meth], x, norm, j, fps, tables[meth]["table1"][0]) for meth in methods}
    positions = {meth: every_position(predictors[meth], x, norm, j, fps) for meth in methods}
    result = {"source": src, "note": "trained checkpoints", "runs": {v: r.run_dir for v, r in runs.items()},
              "num_clips": int(x.shape[0]), "clip_length": int(x.shape[2]), "fps": fps,
              "test_files": [os.path.basename(m.source) for m in motions],
              "steps": {v: m.step for v, m in models.items()},
              "paste_known": sorted(v for v, m in models.items() if m.cfg.model.paste_known),
              "table1": {m: tables[m]["table1"] for m in methods},
              "table1_seconds": {m: tables[m]["table1_seconds"] for m in methods},
              "table2": {m: tables[m]["table2"] for m in methods},
              "time_matched": timed,
              "every_position": {m: {s: {**v, "per_clip": v["per_clip"].tolist()} for s, v in positions[m].items()}
                                 for m in methods},
              "every_position_ratio": {m: {s: ratio_interval(positions[m][s]["per_clip"],
                                                              positions["linear"][s]["per_clip"])
                                           for s in positions[m]} for m in methods if m != "linear"},
              "bones": {m: tables[m]["bones"] for m in methods if tables[m]["bones"] is not None},
              "wall_s": time.time() - t0}
    result["rows"] = _rows(result, methods, _data_name(src))
    result["markdown"] = _markdown(result, methods)
    names = [m.source for m in motions for s in range(0, m.num_frames - proto.CLIP_LENGTH + 1, proto.CLIP_STRIDE)]
    from inbetween_jax.models.cae.calibrate import per_window_rows
    wc = per_window_rows(positions, names[:len(x)], methods, _data_name(src), runs, models)
    wc += in_file_rows(models, runs, motions, src, quick)
    result["rows"] += wc
    result["markdown"] += "\n\n" + "\n\n".join(
        worst_case_markdown([r for r in wc if r["base"] == base and r["split"] == split],
                            f"CAE per {'gap' if 'inside a file' in split else 'clip and gap position'}, {split}")
        for base in dict.fromkeys(r["base"] for r in wc)
        for split in dict.fromkeys(r["split"] for r in wc if r["base"] == base))
    os.makedirs(results_dir, exist_ok=True)
    with open(os.path.join(results_dir, "cae_bench.json"), "w") as fh:
        json.dump({k: v for k, v in result.items() if k != "markdown"}, fh, indent=1)
    with open(os.path.join(results_dir, "cae_bench.md"), "w") as fh:
        fh.write(result["markdown"])
    return result


def in_file_rows(models, runs, test_motions, source: str, quick: bool) -> list:
    """Per-gap rows of each run inside a file (:mod:`.in_file`: ``inbetween infill``'s own path, gate and motion
    matching included) on the test motions and the run's validation split of the run's own training source
    (the embedded clips are too short for 1-2 s gaps): ratio to its base, to the limited Hermite fill and to
    straight lines (:data:`.in_file.BASES`), splits ``"test, inside a file"`` / ``"validation, inside a file"``."""
    from inbetween_jax.models.cae.in_file import base_rows, gap_records
    out = []
    for v, model in models.items():
        val = _val_motions(runs[v].data.get("source") or source, run_val_split(runs[v]))
        for split, motions in (("test", test_motions), ("validation", val)):
            recs = gap_records(model, motions, limit=8 if quick else None)
            share = round(float(np.mean([r["matched"] for r in recs])), 3) if recs else 0.0
            out += [dict(r, variant=v, matched_share=share)
                    for r in base_rows(recs, _data_name(source), f"{split}, inside a file")]
    return out


VAL_METRIC = "val gap error / linear fill's"   # the name selection.json records for :func:`val_score`
VAL_CLIP = 96          # frames per validation clip (a multiple of the CAE's total pooling, 8)


def run_val_split(run) -> str:
    """The validation split that goes with the split ``run`` trained on (``val-subjects`` for
    ``fit-subjects``, else ``val``)."""
    from inbetween_jax.data.datasets import val_split_of
    return val_split_of(run.config.get("train", {}).get("split", "fit"))


def val_score(run, source: str | None) -> float:
    """Checkpoint selection score (lower is better): the run's mean gap error over the time-matched gaps as a
    ratio to linear fill's, on the validation split of ``source`` (files cut from the training data, held out
    of a ``train.split=fit`` run; never the test subjects).  Clips of ``VAL_CLIP`` frames (the CMU validation
    files are 38-137 frames long), so only the 1 s and 2 s gaps fit."""
    from inbetween_jax.data import resolve_source
    from inbetween_jax.evaluation import infilling as proto
    from inbetween_jax.models.cae.infer import fill, load
    model = load(run)
    motions = _val_motions(resolve_source(source or run.data.get("source")), run_val_split(run))
    x = proto.test_clips(motions, model.normalizer, VAL_CLIP, VAL_CLIP // 2)
    fps = float(motions[0].fps)
    ours = _time_matched(lambda inp, mask: fill(model, inp, mask), x, model.normalizer, model.num_joints, fps, None)
    lin = _time_matched(_baseline("linear"), x, model.normalizer, model.num_joints, fps, None)
    return float(np.mean([ours["gaps"][s]["err"][0] / lin["gaps"][s]["err"][0] for s in ours["gaps"]]))


@functools.lru_cache(maxsize=2)
def _val_motions(source: str, split: str = "val") -> list:
    """The validation split's motions of ``source``, read once per process (selection scores every checkpoint)."""
    from inbetween_jax.data import load_motions
    return load_motions(source, split)


def in_table_units(model, norm):
    """``predict(x, mask)`` of a trained model on clips normalised with the table's statistics ``norm`` (the
    first model's): a model trained with other statistics (another source or split) gets its input in its own
    units and its output is put back in the table's, so every row sees the same clips."""
    from inbetween_jax.models.cae.infer import fill
    own = model.normalizer
    if np.array_equal(own.mean, norm.mean) and np.array_equal(own.std, norm.std):
        return lambda inp, mask: fill(model, inp, mask)

    def predict(inp, mask):
        raw = norm.inverse(np.swapaxes(np.asarray(inp, np.float64), -1, -2))
        out = fill(model, np.swapaxes(own(raw), -1, -2).astype(np.float32), mask)
        return np.swapaxes(norm(own.inverse(np.swapaxes(np.asarray(out, np.float64), -1, -2))), -1, -2
                           ).astype(np.float32)
    return predict


def _baseline(name: str):
    """The fill function of a non-learned row: ``predict(x_norm, mask)`` (the input is masked first)."""
    from inbetween_jax.baselines import hermite_fill, linear_fill
    f = {"linear": linear_fill, "hermite": hermite_fill}[name]
    return lambda inp, mask: f(np.asarray(inp, np.float32) * mask, mask)


def _time_matched(predict, x, norm, num_joints: int, fps: float, recon) -> dict:
    """``{"recon": (mean, std) or None, "gaps": {seconds: {"frames", "err": (mean, std)}}}``: one centred gap
    of round(s * fps) frames (skipped when it does not fit the clip); ``predict(x, mask)``: the method (a
    trained model's fill, or :func:`_baseline`)."""
    from inbetween_jax.evaluation.infilling import position_error
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    n, _, t = x.shape
    gaps = {}
    for sec in SECONDS:
        g = int(round(sec * fps))
        if g >= t:
            continue
        a = (t - g) // 2
        fm = np.broadcast_to(gap_frames(t, [(a, a + g)]), (n, t))
        mask = frame_mask_image(fm, num_joints)
        pred = predict(x, mask)
        gaps[sec] = {"frames": g, "err": position_error(pred, x, norm, num_joints, frames=1.0 - fm)}
    return {"recon": recon, "gaps": gaps}


def every_position(predict, x, norm, num_joints: int, fps: float) -> dict:
    """``{seconds: {"frames", "starts", "per_clip"}}``: a gap of round(s * fps) frames put at every start from
    ``POSITION_MARGIN`` in steps of ``POSITION_STRIDE`` while ``POSITION_MARGIN`` known frames stay after it;
    ``per_clip`` (N,) is each clip's mean joint error (cm) over the gap frames of every start.  A clip's gap
    frames are as many at every start, so the mean of ``per_clip`` is the mean over every scored frame."""
    from inbetween_jax.metrics import joint_distances
    from inbetween_jax.models.cae.features import body_positions
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    n, _, t = x.shape
    truth = body_positions(x, norm, num_joints)                       # (N, T, J, 3)
    out = {}
    for sec in SECONDS:
        g = int(round(sec * fps))
        starts = list(range(POSITION_MARGIN, t - g - POSITION_MARGIN + 1, POSITION_STRIDE))
        if not starts:
            continue
        per_clip = np.zeros(n)
        for a in starts:
            fm = np.broadcast_to(gap_frames(t, [(a, a + g)]), (n, t))
            pred = body_positions(predict(x, frame_mask_image(fm, num_joints)), norm, num_joints)
            err = np.asarray(joint_distances(pred[:, a:a + g], truth[:, a:a + g]))   # (N, g, J)
            per_clip += err.mean(axis=(1, 2)) / len(starts)
        out[sec] = {"frames": g, "starts": starts, "per_clip": per_clip}
    return out


def ratio_interval(ours, linear, seed: int = 0) -> dict:
    """``{"ratio", "lo", "hi"}``: mean(ours) / mean(linear) over clips and its 95 % percentile bootstrap
    interval (``BOOTSTRAP`` resamples of the clips, the same clips for both).  Clips cut at half their length
    overlap, so they are not independent and the interval is if anything too narrow."""
    ours, linear = np.asarray(ours, np.float64), np.asarray(linear, np.float64)
    idx = np.random.default_rng(seed).integers(0, len(ours), (BOOTSTRAP, len(ours)))
    boot = ours[idx].sum(1) / linear[idx].sum(1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return {"ratio": float(ours.sum() / linear.sum()), "lo": float(lo), "hi": float(hi)}


def _rows(r, methods, data) -> list:
    """Flat records: tables ``cae_table1`` (frames, gap_s), ``cae_table2`` (corruption), ``cae_bones``."""
    from inbetween_jax.evaluation import flat_rows
    from inbetween_jax.evaluation.infilling import GAPS, GAPS_SECONDS
    out = []
    for m in methods:
        model = None if m in BASELINES else "cae"
        gaps = {g: ms for g, ms in zip(GAPS, r["table1"][m])}
        gaps.update({g: ms for g, ms in zip(GAPS_SECONDS, r["table1_seconds"][m])})
        gaps.update({v["frames"]: v["err"] for v in r["time_matched"][m]["gaps"].values()})
        t1 = [{"method": m, "frames": g, "gap_s": round(g / r["fps"], 3), "mpjpe_cm": ms[0], "mpjpe_std_cm": ms[1]}
              for g, ms in sorted(gaps.items()) if ms is not None]
        out += flat_rows(t1, "cae_table1", data, model, keys=("frames", "gap_s"))
        lin = r["time_matched"]["linear"]["gaps"]
        tm = [{"method": m, "frames": v["frames"], "gap_s": float(s), "ratio_to_linear": v["err"][0] / lin[s]["err"][0]}
              for s, v in r["time_matched"][m]["gaps"].items() if m != "linear"]
        out += flat_rows(tm, "cae_time_matched", data, model, keys=("frames", "gap_s"))
        ep = [{"method": m, "frames": r["every_position"][m][s]["frames"], "gap_s": float(s),
               "mpjpe_cm": float(np.mean(r["every_position"][m][s]["per_clip"])),
               **({} if m == "linear" else {f"ratio_to_linear{k}": v
                                            for k, v in (("", r["every_position_ratio"][m][s]["ratio"]),
                                                         ("_lo95", r["every_position_ratio"][m][s]["lo"]),
                                                         ("_hi95", r["every_position_ratio"][m][s]["hi"]))})}
              for s in r["every_position"][m]]
        out += flat_rows(ep, "cae_every_position", data, model, keys=("frames", "gap_s"))
        t2 = [{"method": m, "corruption": k, "mpjpe_cm": ms[0], "mpjpe_std_cm": ms[1]}
              for k, ms in r["table2"][m].items()]
        out += flat_rows(t2, "cae_table2", data, model, keys=("corruption",))
        if m in r["bones"]:
            out += flat_rows([{"method": m, **r["bones"][m]}], "cae_bones", data, model, keys=())
    return out


def _pasted(r, method: str) -> str:
    """The mark of a cell that a ``model.paste_known`` run fills with its input unchanged (every entry known:
    the clean clip, or the noisy one of Table 2), so its number is the input's, not the network's."""
    return " (input: paste_known)" if method in r.get("paste_known", ()) else ""


def _markdown(r, methods) -> str:
    from inbetween_jax.evaluation import markdown_table
    from inbetween_jax.evaluation.infilling import PS, SIGMAS
    fps = r["fps"]
    lin = r["time_matched"]["linear"]["gaps"]
    secs = list(lin)
    tm_cols = ["reconstruction (no gap)"] + [f"{s} s ({lin[s]['frames']} fr)" for s in secs]
    tm = []
    for m in methods:
        g = r["time_matched"][m]["gaps"]
        row = {"Model": _label(m), tm_cols[0]: _fmt(r["time_matched"][m]["recon"]) + _pasted(r, m)}
        for s, c in zip(secs, tm_cols[1:]):
            ratio = "" if m == "linear" else f" [x{g[s]['err'][0] / lin[s]['err'][0]:.2f}]"
            row[c] = _fmt(g[s]["err"]) + ratio
        tm.append(row)
    ep_lin = r["every_position"]["linear"]
    ep_cols = [f"{s} s ({v['frames']} fr, {len(v['starts'])} starts)" for s, v in ep_lin.items()]
    ep = [{"Model": _label(m), **{c: f"{np.mean(r['every_position'][m][s]['per_clip']):.2f}" + (
        "" if m == "linear" else " [x{ratio:.2f}, {lo:.2f}-{hi:.2f}]".format(**r["every_position_ratio"][m][s]))
        for s, c in zip(ep_lin, ep_cols)}} for m in methods]
    t1 = [{"Model": _label(m), **{f"{g} Frames": _fmt(v) + (_pasted(r, m) if g == 0 else "")
                                  for g, v in zip((0, 60, 120), r["table1"][m])},
           "paper 0 / 60 / 120": " / ".join(PAPER_T1[m.partition(":")[0].split("_")[0]])} for m in methods]
    t1s = [{"Model": _label(m), **{f"{g} Frames": _fmt(v) + (_pasted(r, m) if g == 0 else "")
                                   for g, v in zip((0, 30, 60), r["table1_seconds"][m])}}
           for m in methods]
    keys = [f"sigma={s}" for s in SIGMAS] + [f"p={p}" for p in PS]
    t2 = [{"Model": _label(m), **{k: _fmt(r["table2"][m][k]) + (_pasted(r, m) if k.startswith("sigma") else "")
                                  for k in keys}} for m in methods]
    bones = [{"Model": _label(m), "median - GT median": b["mean_abs_median_dev_cm"], "std": b["mean_std_cm"],
              "IQR": b["mean_iqr_cm"], "GT std": b["gt_mean_std_cm"]} for m, b in r["bones"].items()]
    parts = [
        f"CAE benchmark -- {r['note']}; data: {r['source']} test split ({', '.join(r['test_files'])}), "
        f"{r['num_clips']} clips of {r['clip_length']} frames at {fps:.0f} Hz; 3D joint error in cm, "
        "mean (± std), root-aligned.",
        markdown_table(tm, tuple(tm_cols), f"Time-matched gaps at {fps:.0f} Hz (scored over the gap; [x r]: ratio "
                       "to linear fill; reconstruction: the clean clip, every frame scored)", keys=("Model",)),
        markdown_table(ep, tuple(ep_cols), f"The same gaps at every position (a start every {POSITION_STRIDE} "
                       f"frames, {POSITION_MARGIN} known frames kept at either end; mean error in cm; [x r, lo-hi]: "
                       f"ratio to linear fill and its 95 % bootstrap interval over the {r['num_clips']} clips, which overlap "
                       "by half, so it is if anything too narrow)",
                       keys=("Model",)),
        markdown_table(t1, ("0 Frames", "60 Frames", "120 Frames", "paper 0 / 60 / 120"),
                       "Table 1 (gap in frames; scored over the gap)", keys=("Model",)),
        markdown_table(t1s, ("0 Frames", "30 Frames", "60 Frames"),
                       f"Table 1b (same durations as the paper's 60 Hz gaps: 30 / 60 frames at {fps:.0f} Hz = "
                       "1 s / 2 s)", keys=("Model",)),
        markdown_table(t2, keys, "Table 2 (de-noising; every frame scored; sigma in normalised units; linear "
                       "row for sigma: the noisy input itself, as for a paste_known run)", keys=("Model",)),
        markdown_table(bones, ("median - GT median", "std", "IQR", "GT std"),
                       "Bone lengths on reconstruction (cm): mean over bones; a paste_known run's "
                       "reconstruction is its input", keys=("Model",), digits=2)]
    return "\n\n".join(parts) + "\n"

