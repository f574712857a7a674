"""S-CVAE rows of the paper's Table 1 layout (plus MMPE) beside Slerp, on the benchmark windows.

``run(source, results_dir, run_dir, quick)``: keyframes at frame 9 (one past frame) and 9 + L + 1 for
L = 10, 30, 50 (whatever ``data.trans_max`` the run was trained with); APD over 10 samples; accuracy metrics averaged over the
samples.  Also writes ``<results>/scvae_error_over_time.png``: the per-frame joint position error along the
longest transition (mean over windows and samples, band = min..max over the samples averaged over windows)
with Slerp dashed, as Fig. 6 of the S-CVAE paper.  Without a trained run the section is skipped (one line).
"""
from __future__ import annotations

import functools
import os
import time

import numpy as np

from inbetween_jax.models.scvae.bank import bank_enabled, bank_searched, blend, sampled_mode

N_PAST = 10
LENGTHS = (10, 30, 50)
NUM_SAMPLES = 10


def _skipped(why: str, source=None) -> dict:
    md = f"**S-CVAE**: skipped, {why} (train one with `inbetween train scvae`)."
    return {"markdown": md, "rows": [], "skipped": why, "source": source}


def run(source, results_dir: str, run_dir: str | None, quick: bool = False) -> dict:
    """Table-1 rows of the run in ``run_dir`` on ``source``'s benchmark windows.

    Returns ``{"markdown", "rows": [flat records], "table": [row dicts], "step", "source", "windows", "plots"}``;
    a run folder that is missing, holds no checkpoint, or was trained on another skeleton gives a skip line.
    """
    from inbetween_jax import metrics
    from inbetween_jax.data import l2p_stats, load_dataset, resolve_source
    from inbetween_jax.evaluation import TABLE_COLUMNS, baseline_table1, flat_rows, markdown_table, transition_metrics
    from inbetween_jax.evaluation.worst_case import worst_case_markdown, worst_case_rows
    from inbetween_jax.models.ood_runs import calibration_worst_case
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.context import HERMITE_NAME, IN_CLIP_NAME, in_clip
    from inbetween_jax.models.scvae.gate import gate_windows
    from inbetween_jax.models.scvae.samples import COLUMNS as SAMPLE_COLUMNS
    from inbetween_jax.models.scvae.samples import RATIO_COLUMNS, length_rows
    from inbetween_jax.train.run import RunError, load_run

    t0 = time.time()
    source = resolve_source(source)
    if run_dir is None:
        return _skipped("no run folder given", source)
    try:
        run_ = load_run(run_dir)
    except RunError as e:
        return _skipped(str(e), source)
    if run_.model != "scvae":
        return _skipped(f"`{run_dir}` holds a {run_.model} run", source)
    train = load_dataset(source, "train")
    bench = load_dataset(source, "benchmark")
    joints = int(train.local_quats.shape[2])
    if run_.extra.get("num_joints", joints) != joints:
        return _skipped(f"the run in `{run_dir}` was trained on a {run_.extra['num_joints']}-joint skeleton "
                        f"({run_.data.get('source')}) and this source has {joints} joints", source)
    trained = infer.load(run_)
    lengths = tuple(n for n in LENGTHS if N_PAST + n < bench.window)
    if not lengths:
        return _skipped(f"the {bench.window}-frame benchmark windows hold no {min(LENGTHS)}-frame transition", source)
    x_mean, x_std = l2p_stats(train.global_pose()[1])
    note = f"Run `{run_dir}` at step {trained.step}. "
    if quick:
        bench = bench.take(slice(0, 64))
        note += f"Quick: first {len(bench)} benchmark windows. "
    rows = [r for r in baseline_table1(bench, x_mean, x_std, lengths, N_PAST) if r["method"] == "Slerp"]
    longest = None
    model_cfg = trained.cfg.model
    gated = trained.gate is not None and model_cfg.ood_gate
    fa = tuple(trained.extra.get("forward_axis") or bench.skeleton.forward_axis())
    per_window, sample_table, clip_window = [], [], []
    use_bank, show_bank = (trained.bank is not None and f(model_cfg) for f in (bank_enabled, bank_searched))
    for length in lengths:
        s = infer.sample_transitions(model_cfg, trained.state, bench, N_PAST, length, NUM_SAMPLES, bank=trained.bank,
                                     blend_bank=False, sampled=False)
        if show_bank:      # what the bank gives alone (the base of model.bank_base, blended in by bank_weight)
            q, r = s["bank_q"], s["bank_r"]
            rows.append({"method": bank_alone_name(model_cfg), "frames": length, "MMPE": None,
                         **transition_metrics(bench, N_PAST, length, q, r, x_mean, x_std)})
        if use_bank:       # the network alone, then network and bank blended
            rows.append({"method": NETWORK_ALONE, "frames": length, "MMPE": None,
                         **transition_metrics(bench, N_PAST, length, s["q"], s["r"], x_mean, x_std)})
            s = dict(s, **dict(zip(("q", "r"), blend(s["q"], s["r"], q, r, model_cfg.bank_weight))))
        variants, weight = [("S-CVAE", s["q"], s["r"])], None
        clip_q, clip_r = s["q"], s["r"]      # what goes onto the Hermite path inside a clip (gated below)
        if gated:          # the network before the gate, then the gated samples (models/ood.py)
            rows.append({"method": UNGATED, "frames": length, "MMPE": None,
                         **transition_metrics(bench, N_PAST, length, s["q"], s["r"], x_mean, x_std)})
            q, r, _, weight = gate_windows(trained.gate, bench, N_PAST - 1, N_PAST + length, s["q"], s["r"], fa)
            variants = [(UNGATED, s["q"], s["r"]), ("S-CVAE", q, r)]
            clip_q, clip_r = q, r
            if trained.context_gate is not None and model_cfg.context_gate:    # its own thresholds there
                clip_q, clip_r = gate_windows((trained.gate[0], trained.context_gate), bench, N_PAST - 1,
                                              N_PAST + length, s["q"], s["r"], fa)[:2]
            s = dict(s, q=q, r=r)
        if trained.bank is not None and sampled_mode(model_cfg, NUM_SAMPLES):   # samples table only
            variants.append((SAMPLED, *infer.bank_samples(trained.bank, model_cfg, bench, N_PAST, length, s["q"],
                                                          s["r"], weight)))
        sample_table += length_rows(bench, N_PAST, length, x_mean, x_std, variants)
        per_window += window_ratios(bench, N_PAST, length, s["q"], s["r"])
        if model_cfg.context_base:     # inside a clip: onto the Hermite path through the frames beside the keyframes
            cq, cr, hq, hr = in_clip(bench, N_PAST, length, clip_q, clip_r, model_cfg)
            rows += [{"method": name, "frames": length, "MMPE": None,
                      **transition_metrics(bench, N_PAST, length, q_, r_, x_mean, x_std)}
                     for name, q_, r_ in ((HERMITE_NAME, hq, hr), (IN_CLIP_NAME, cq, cr))]
            clip_window += window_ratios(bench, N_PAST, length, cq, cr)
            if trained.bank is not None and sampled_mode(model_cfg, NUM_SAMPLES):   # as infill, inside a clip
                sq_, sr_ = infer.bank_samples(trained.bank, model_cfg, bench, N_PAST, length, cq, cr, weight,
                                              spread=model_cfg.timing_spread_in_clip)
                sample_table += length_rows(bench, N_PAST, length, x_mean, x_std,
                                            [(IN_CLIP_NAME, cq, cr), (SAMPLED_IN_CLIP, sq_, sr_)])[1:]
        if length == max(lengths):
            longest = s
        row = {"method": "S-CVAE", "frames": length,
               **transition_metrics(bench, N_PAST, length, s["q"], s["r"], x_mean, x_std)}
        row["MMPE"] = (float(metrics.mmpe(s["mid_f"][:, :, None], s["mid_b"][:, :, None], mid_index=0))
                       if "mid_f" in s else None)
        rows.append(row)
    order = {"Slerp": 0, "S-CVAE": 1, NETWORK_ALONE: 2, UNGATED: 3, HERMITE_NAME: 4, IN_CLIP_NAME: 5}
    rows.sort(key=lambda r: (r["frames"], order.get(r["method"], 3)))
    cols = tuple(TABLE_COLUMNS) + ("MMPE",)
    variant = f"S-CVAE ({run_.preset})"
    for r in rows:
        if r["method"] == "S-CVAE":
            r["method"] = variant
    md = markdown_table(rows, cols, f"S-CVAE, Table 1 layout ({len(bench)} windows, {NUM_SAMPLES} samples)")
    for r in sample_table:
        if r["method"] == "S-CVAE":
            r["method"] = variant
    md += "\n\n" + markdown_table(sample_table, SAMPLE_COLUMNS + RATIO_COLUMNS,
                                  f"S-CVAE as a generative model: {NUM_SAMPLES} samples per keyframe pair (APD in m, "
                                  f"pairwise / mean / best in cm, ratios to Slerp's error)")
    official = official_rows(trained, bench, x_mean, x_std, variant)
    vel = "with" if trained.cfg.model.uses_past_frame else "without"
    md += "\n\n" + markdown_table(official, ("L2Q", "L2P", "NPSS"),
                                  f"S-CVAE, official LaFAN1 protocol (10 past frames; the model uses them {vel} the "
                                  f"past frame's root velocity; metrics averaged over {NUM_SAMPLES} samples)")
    wc = worst_case_rows(per_window, "per_window", data_name(source), "scvae", "Slerp", "test")
    wc += calibration_worst_case(run_.run_dir, trained.gate, "scvae", "Slerp")
    md += "\n\n" + worst_case_markdown([r for r in wc if r["split"] == "test"],
                                        f"S-CVAE per window, test windows{' (gated)' if gated else ''}")
    clip = worst_case_rows(clip_window, "per_window", data_name(source), "scvae", "Slerp", "test, inside a clip")
    if clip:
        md += "\n\n" + worst_case_markdown(clip, f"{IN_CLIP_NAME}, per window, test windows")
    if any(r["split"] not in ("test", "test, inside a clip") for r in wc):
        md += "\n\n" + worst_case_markdown([r for r in wc if r["split"] not in ("test", "test, inside a clip")],
                                            "S-CVAE per window, validation subjects (the gate's calibration windows)")
    os.makedirs(results_dir, exist_ok=True)
    plot = error_over_time_plot(bench, max(lengths), longest, "S-CVAE",
                                os.path.join(results_dir, "scvae_error_over_time.png"))
    md += (f"\n\n{note}APD/ADE/SLDE in m, FootSlide in cm/frame, MMPE in cm. Error along the {max(lengths)}-frame "
           f"transition: `{os.path.basename(plot)}`. Wall {time.time() - t0:.0f} s.")
    data = data_name(source)
    records = (flat_rows([r for r in rows if r["method"] == "Slerp"], "table1", data, model="slerp")
               + flat_rows([r for r in rows if r["method"] == variant], "table1", data, model="scvae",
                           variant=run_.preset)
               + flat_rows([r for r in official if r["method"] == variant], "official", data, model="scvae",
                           variant=run_.preset)
               + flat_rows([r for r in official if r["method"] == velocity_baseline_name(trained.cfg.model)],
                           "official", data, model="slerp_velocity"))
    for table, rs in (("table1", rows), ("official", official)) if show_bank else ():
        records += flat_rows([r for r in rs if r["method"] == NETWORK_ALONE], table, data, model="scvae",
                             variant=f"{run_.preset}, network alone")
        name = bank_alone_name(model_cfg)
        records += flat_rows([r for r in rs if r["method"] == name], table, data, model="bank", variant=name)
    for table, rs in (("table1", rows),) if gated else ():
        records += flat_rows([r for r in rs if r["method"] == UNGATED], table, data, model="scvae",
                             variant=f"{run_.preset}, network alone (no gate)")
    records += (wc + clip + flat_rows([r for r in rows if r["method"] == HERMITE_NAME], "table1", data,
                                      model="hermite_context")
                + flat_rows([r for r in rows if r["method"] == IN_CLIP_NAME], "table1", data, model="scvae",
                            variant=f"{run_.preset}, inside a clip"))
    for method, model, var in (("Slerp", "slerp", ""), (variant, "scvae", run_.preset),
                               (UNGATED, "scvae", f"{run_.preset}, network alone (no gate)"),
                               (SAMPLED, "scvae", f"{run_.preset}, sampled mode"),
                               (IN_CLIP_NAME, "scvae", f"{run_.preset}, inside a clip"),
                               (SAMPLED_IN_CLIP, "scvae", f"{run_.preset}, sampled mode, inside a clip")):
        records += flat_rows([r for r in sample_table if r["method"] == method], "samples", data, model=model,
                             variant=var)
    return {"markdown": md, "rows": records, "table": rows, "step": trained.step, "source": source,
            "windows": len(bench), "plots": [plot]}


OFFICIAL_LENGTHS = (5, 15, 30, 45)
VELOCITY_BASELINE = "Slerp + start velocity (Hermite)"
NETWORK_ALONE = "S-CVAE, network alone (no bank)"
SAMPLED = "S-CVAE, sampled mode"
SAMPLED_IN_CLIP = "S-CVAE inside a clip, sampled mode"
UNGATED = "S-CVAE, network alone (no out-of-distribution gate)"


def data_name(source) -> str:
    from inbetween_jax.data.datasets import is_lafan1
    return "lafan1" if is_lafan1(source) else source if source in ("embedded", "cmu") else "bvh"


def window_ratios(windows, n_past: int, n_trans: int, q, r) -> list:
    """Per-window records (:mod:`inbetween_jax.evaluation.worst_case`): mean joint position error of the samples
    q (S, B, L, J, 4), r (S, B, L, 3) over Slerp's, per window."""
    from inbetween_jax.baselines import interpolate_transition
    sq, sr = interpolate_transition(windows.local_quats.astype(np.float64), windows.root_pos.astype(np.float64),
                                    n_past, n_trans)
    base = per_frame_error(windows, n_past, n_trans, sq[None], sr[None])[0].mean(-1)
    ours = per_frame_error(windows, n_past, n_trans, q, r).mean((0, 2))
    return [{"name": windows.seq_names[i], "frames": n_trans, "ratio": float(ours[i] / max(base[i], 1e-6))}
            for i in range(len(windows))]


def bank_alone_name(model_cfg) -> str:
    return f"Transition bank alone (k {model_cfg.bank_k}, no network)"


def base_damping(model_cfg) -> float:
    """The damping of the velocity path shown beside a model: its own residual base's, else 0 (the plain cubic)."""
    return model_cfg.base_damping if model_cfg.base_velocity else 0.0


def velocity_baseline_name(model_cfg) -> str:
    """The official table's name of the velocity path shown beside a model (:func:`base_damping`)."""
    d = base_damping(model_cfg)
    return VELOCITY_BASELINE if not d else VELOCITY_BASELINE[:-1] + f", damped {d:g} / frame)"


def official_rows(trained, bench, x_mean, x_std, name: str) -> list:
    """Interpolation, interpolation continuing the last past frame's velocity
    (:func:`~inbetween_jax.baselines.velocity_interpolate_transition`, with the model's ``base_damping`` when it
    uses that path as its residual base) and the model under the official LaFAN1 protocol (10 past frames, L2Q /
    L2P / NPSS at 5 / 15 / 30 / 45 frames); the model's errors are the mean over ``NUM_SAMPLES`` samples."""
    from inbetween_jax.evaluation import official_baseline_table
    from inbetween_jax.evaluation.lafan1 import official_errors
    from inbetween_jax.models.scvae import infer
    lengths = [n for n in OFFICIAL_LENGTHS if n <= trained.cfg.data.trans_max and N_PAST + n < bench.window]
    from inbetween_jax.baselines import velocity_interpolate_transition
    rows = [r for r in official_baseline_table(bench, x_mean, x_std, lengths, N_PAST) if r["method"] != "Zero-velocity"]
    base = velocity_baseline_name(trained.cfg.model)
    for n in lengths:   # the residual base of ``model.base_velocity``, on its own (nothing learned)
        q, r = velocity_interpolate_transition(bench.local_quats, bench.root_pos, N_PAST, n,
                                               base_damping(trained.cfg.model))
        rows.append({"method": base, "frames": n,
                     **official_errors(bench, N_PAST, n, q, r, x_mean, x_std)})
    use_bank, show_bank = (trained.bank is not None and f(trained.cfg.model) for f in (bank_enabled, bank_searched))

    def mean_errors(n, qs, rs):           # over the samples
        per = [official_errors(bench, N_PAST, n, q, r, x_mean, x_std) for q, r in zip(qs, rs)]
        return {k: float(np.mean([p[k] for p in per])) for k in per[0]}

    for n in lengths:
        s = infer.sample_transitions(trained.cfg.model, trained.state, bench, N_PAST, n, NUM_SAMPLES, velocity=True,
                                     bank=trained.bank, blend_bank=False, gate=getattr(trained, "gate", None),
                                     sampled=False)        # the fill, as the Table-1 rows (the samples: their table)
        q, r = s["q"], s["r"]
        if show_bank:
            bq, br = s["bank_q"], s["bank_r"]
            rows.append({"method": bank_alone_name(trained.cfg.model), "frames": n,
                         **official_errors(bench, N_PAST, n, bq, br, x_mean, x_std)})
        if use_bank:
            rows.append({"method": NETWORK_ALONE, "frames": n, **mean_errors(n, q, r)})
            q, r = blend(q, r, bq, br, trained.cfg.model.bank_weight)
        rows.append({"method": name, "frames": n, **mean_errors(n, q, r)})
    order = {"Slerp": 0, base: 1, name: 2, bank_alone_name(trained.cfg.model): 3, NETWORK_ALONE: 4}
    return sorted(rows, key=lambda r: (r["frames"], order.get(r["method"], 2)))


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


VAL_LENGTHS = (10, 30, 50)
VAL_SAMPLES = 2


@functools.lru_cache(maxsize=2)
def _val_windows(source: str, split: str = "val"):
    """The validation windows of ``source`` and their L2P statistics, read once per process (checkpoint
    selection scores every checkpoint of a run on the same windows)."""
    from inbetween_jax.data import l2p_stats, load_dataset
    val = load_dataset(source, split, window=N_PAST + max(VAL_LENGTHS) + 5, offset=20)
    x_mean, x_std = l2p_stats(val.global_pose()[1])
    return val, x_mean, x_std


def val_score(run, source: str) -> float:
    """Checkpoint-selection score (lower is better): mean L2P over transitions of 10 / 30 / 50 frames on the
    validation split of ``source`` (65-frame windows at offset 20, 10 past frames; statistics of the
    validation windows themselves), ``VAL_SAMPLES`` samples each; a model trained with the past frame's
    velocity gets it (the protocol it is built for).  Never uses test windows."""
    from inbetween_jax.evaluation import transition_metrics
    from inbetween_jax.models.scvae import infer
    trained = infer.load(run)
    from inbetween_jax.models.cae.bench import run_val_split
    val, x_mean, x_std = _val_windows(source, run_val_split(run))
    lengths = [n for n in VAL_LENGTHS if n <= trained.cfg.data.trans_max]
    errs = []
    for n in lengths:
        s = infer.sample_transitions(trained.cfg.model, trained.state, val, N_PAST, n, VAL_SAMPLES, velocity=True,
                                     bank=trained.bank, blend_bank=False)
        errs.append(transition_metrics(val, N_PAST, n, s["q"], s["r"], x_mean, x_std)["L2P"])
    return float(np.mean(errs))
