"""Two-character in-betweening benchmark in the layout of the interaction paper's Table 1.

``run(source, results_dir, ckpt_dir, quick)`` evaluates, on the test split of the paired data:
the cross-space model (``ckpt_dir``), the independent-characters baseline (the same network trained with
``model.interaction=false model.gan=false``, found next to ``ckpt_dir``: ``<ckpt_dir>_indep``, a ``_full`` ->
``_indep`` sibling, or ``ckpt_dir/indep``) and per-character interpolation, plus ground truth for the
interaction score.  Ablations: the same checkpoint with the refiner switched off, and ``<ckpt_dir>_nogan``
(trained with ``model.gan=false``) when present.  Without a checkpoint the networks are trained for a few steps only and labelled untrained.

Columns: L2P / L2Q at 30 and 50 transition frames, foot skating (first 50 frames, clamp(2 - 2^(h/H)),
H = 2.5 cm, cm/frame), interaction score at 40 / 60 / 80 frames, diversity (APD over 10 samples, metres)
at 30 / 50, Frechet distance of classifier features and 100 x NPSS at 100 / 150 / 200 frames.
"""
from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time

import numpy as np

PAPER_BOXING = dict(l2p_30=0.192, l2p_50=0.208, l2q_30=0.254, l2q_50=0.279, foot_50=0.342, inter_40=0.914,
                    inter_60=0.911, inter_80=0.905, div_30=1.104, div_50=1.802, fid_100=0.282, fid_150=0.287,
                    fid_200=0.289, npss_100=1.398, npss_150=1.430, npss_200=1.531)
COLUMNS = list(PAPER_BOXING)
N_INPUT = 20


def _find_runs(ckpt_dir):
    if ckpt_dir is None:
        return None, None
    ckpt_dir = os.path.normpath(ckpt_dir)
    if os.path.basename(ckpt_dir) == "checkpoints":
        ckpt_dir = os.path.dirname(ckpt_dir)
    if os.path.exists(os.path.join(ckpt_dir, "interaction_meta.json")):
        full = ckpt_dir
        cands = [ckpt_dir + "_indep", ckpt_dir.replace("_full", "_indep"), os.path.join(ckpt_dir, "indep")]
    else:
        full = os.path.join(ckpt_dir, "full")
        cands = [os.path.join(ckpt_dir, "indep")]
    indep = next((c for c in cands if c != full and os.path.exists(os.path.join(c, "interaction_meta.json"))), None)
    return full, indep


def _quick_train(source, run_dir, steps, extra):
    from train_interaction import main as train_main
    train_main(["--run-dir", run_dir, f"train.num_steps={steps}", f"train.ckpt_every={steps}",
                f"train.log_every={steps}", "train.batch_size=8"] + (["--source", source] if source else []) + extra)
    return run_dir


def _model_method(cfg, nets, params, fa, use_refiner=None):
    import jax
    from inbetween_jax.models.interaction import sample_rollouts
    cache = {}

    def method(b, steps, samples, key):
        if (steps, samples) not in cache:
            cache[(steps, samples)] = jax.jit(lambda p, w, kp, R, t, k: sample_rollouts(
                nets, p, w, kp, R, t, k, cfg, fa, steps, samples, threshold=-1.0, use_refiner=use_refiner)[0])
        return np.asarray(cache[(steps, samples)](params, b["x"][:, :, :N_INPUT], b["keypose"], b["rel_R"],
                                                  b["rel_t"], key))
    return method


def _interp_method(b, steps, samples, key):
    from inbetween_jax.models.interaction_eval import interpolation_inbetween
    L = b["x"].shape[2] - N_INPUT - 1
    out = np.asarray(interpolation_inbetween(b["x"][:, :, N_INPUT - 1], b["keypose"], L))
    pad = np.repeat(out[:, :, -1:], steps * 10 - L, axis=2) if steps * 10 > L else out[:, :, :0]
    return np.repeat(np.concatenate([out, pad], 2)[None], samples, 0)


def _gt_method(b, steps, samples, key):
    L = b["x"].shape[2] - N_INPUT - 1
    out = b["x"][:, :, N_INPUT:N_INPUT + L]
    pad = np.repeat(out[:, :, -1:], steps * 10 - L, axis=2) if steps * 10 > L else out[:, :, :0]
    return np.repeat(np.concatenate([out, pad], 2)[None], samples, 0)


def evaluate(method, windows, stats, cls, feet, pos_scale, key, num_div=10):
    """Table-1 metrics of one method. windows: {length: eval_windows dict}. Returns {column: value}."""
    import jax
    import jax.numpy as jnp
    from inbetween_jax import metrics
    from inbetween_jax.models.interaction_eval import classify_windows, frechet_distance, global_quats, to_common
    res = {}
    for L, b in windows.items():
        if not b:
            continue
        steps = math.ceil(L / 10)
        want_div = L in (30, 50)
        pred = method(b, steps, num_div if want_div else 1, jax.random.fold_in(key, L))[:, :, :, :L]
        gt = b["x"][:, :, N_INPUT:N_INPUT + L]
        prev = b["x"][:, :, N_INPUT - 1]
        P = np.asarray(to_common(jnp.asarray(pred[0]), b["rel_R"], b["rel_t"]))         # (B, 2, L, J, 9)
        G = np.asarray(to_common(jnp.asarray(gt), b["rel_R"], b["rel_t"]))
        prevc = np.asarray(to_common(jnp.asarray(prev[:, :, None]), b["rel_R"], b["rel_t"]))[:, :, 0]
        if L in (30, 50):
            res[f"l2p_{L}"] = float(np.mean([metrics.l2p(P[:, c, ..., :3], G[:, c, ..., :3], *stats) for c in (0, 1)]))
            qp, qg = global_quats(jnp.asarray(P), prevc), global_quats(jnp.asarray(G), prevc)
            res[f"l2q_{L}"] = float(np.mean([metrics.l2q(qp[:, c], qg[:, c]) for c in (0, 1)]))
            allc = np.stack([np.asarray(to_common(jnp.asarray(s), b["rel_R"], b["rel_t"])) for s in pred])
            res[f"div_{L}"] = float(metrics.apd(allc[..., :3].reshape(allc.shape[:2] + (-1,))))
        if L == 50:
            cm = P[..., :3] / pos_scale
            res["foot_50"] = float(np.mean([metrics.foot_skating(cm[:, c], feet) for c in (0, 1)]))
        if L in (40, 60, 80):
            clip = np.concatenate([prevc[:, :, None], P], 2)
            prob, _ = classify_windows(*cls, jnp.asarray(clip))
            res[f"inter_{L}"] = float(np.mean(prob))
        if L in (100, 150, 200):
            _, fp = classify_windows(*cls, jnp.asarray(np.concatenate([prevc[:, :, None], P], 2)), stride=30)
            _, fg = classify_windows(*cls, jnp.asarray(np.concatenate([prevc[:, :, None], G], 2)), stride=30)
            fp, fg = np.asarray(fp).reshape(-1, fp.shape[-1]), np.asarray(fg).reshape(-1, fg.shape[-1])
            res[f"fid_{L}"] = frechet_distance(fp, fg) if len(fp) > 2 else float("nan")
            qp, qg = global_quats(jnp.asarray(P), prevc), global_quats(jnp.asarray(G), prevc)
            B = qp.shape[0]
            res[f"npss_{L}"] = 100.0 * float(metrics.npss(jnp.moveaxis(qg, 1, 2).reshape(B, L, -1),
                                                          jnp.moveaxis(qp, 1, 2).reshape(B, L, -1)))
    return res


def stop_stats(cfg, nets, params, fa, b) -> dict:
    """Inference as in the paper: roll out until both characters are within ``model.stop_threshold`` of their
    keyposes (cap ``model.max_frames``).  b: eval windows.  -> reached fraction, mean frames, true gap."""
    import jax
    from inbetween_jax.models.interaction import rollout
    from inbetween_jax.models.interaction import keypose_distance
    steps = cfg.model.max_frames // cfg.data.n_pred
    l = cfg.data.n_pred
    frames, length = jax.jit(lambda p: rollout(nets, p, b["x"][:, :, :N_INPUT], b["keypose"], b["rel_R"],
                                               b["rel_t"], jax.random.key(0), cfg, fa, steps))(params)
    length = np.asarray(length)
    d = np.stack([np.asarray(keypose_distance(frames[:, :, l * k + l - 1], b["keypose"])).max(1)
                  for k in range(steps)], 1)                                  # (B, steps), metres
    return dict(reached=float(np.mean(length < steps * l)), mean_frames=float(length.mean()),
                true_gap=int(b["x"].shape[2] - N_INPUT - 1), threshold_m=cfg.model.stop_threshold,
                max_frames=cfg.model.max_frames, median_closest_m=float(np.median(d.min(1))))


def format_table(rows: dict, note: str) -> str:
    head = ("| method | L2P 30 | L2P 50 | L2Q 30 | L2Q 50 | Foot 50 | Inter 40 | Inter 60 | Inter 80 | Div 30 | "
            "Div 50 | FD 100 | FD 150 | FD 200 | 100xNPSS 100 | 100xNPSS 150 | 100xNPSS 200 |")
    lines = [note, "", head, "|" + "---|" * (len(COLUMNS) + 1)]
    for name, r in rows.items():
        lines.append(f"| {name} | " + " | ".join("n/a" if not isinstance(r.get(c), float) or math.isnan(r[c])
                                                  else f"{r[c]:.3f}" for c in COLUMNS) + " |")
    return "\n".join(lines)


def run(source: str | None, results_dir: str, ckpt_dir: str | None, quick: bool) -> dict:
    """Evaluate and write ``results_dir/interaction_table.{md,json}``; returns the rows dict."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import jax
    from inbetween_jax.models.interaction_data import eval_windows, load_pairs, sample_batch, split_pairs
    from inbetween_jax.models.interaction_eval import restore_run, to_common, train_classifier
    t0 = time.time()
    full_dir, indep_dir = _find_runs(ckpt_dir)
    untrained = full_dir is None or not os.path.exists(os.path.join(full_dir, "interaction_meta.json"))
    tmp = None
    if untrained:
        tmp = tempfile.mkdtemp(prefix="bench_interaction_")
        steps = 3 if quick else 20
        full_dir = _quick_train(source, os.path.join(tmp, "full"), steps, [])
        indep_dir = _quick_train(source, os.path.join(tmp, "indep"), steps, ["model.interaction=false",
                                                                              "model.gan=false"])
    cfg, nets, params, meta = restore_run(full_dir)
    d = cfg.data
    data_source = meta["source"] if source is None else source
    pairs = load_pairs(data_source, d.pair_distance)
    if pairs[0].feats.shape[2] != meta["num_joints"]:      # the checkpoint was trained on another skeleton
        data_source = meta["source"]
        pairs = load_pairs(data_source, d.pair_distance)
    train, test = split_pairs(pairs, "train", d.split), split_pairs(pairs, "test", d.split)
    fa = np.asarray(meta["forward_axis"], np.float32)
    constructed = any(p.constructed for p in pairs)
    max_w = 24 if quick else 128
    lengths = (30, 40, 50, 60, 80, 100, 150, 200)
    windows = {L: eval_windows(test, N_INPUT, L, 10 if L <= 80 else 30, d.pos_scale, max_w) for L in lengths}
    rng = np.random.default_rng(0)
    sb = sample_batch(train, rng, 256, 50, (d.key_min, d.key_max), False, d.pos_scale)
    common = np.asarray(to_common(sb["x"], sb["rel_R"], sb["rel_t"]))[..., :3]   # (N, 2, T, J, 3)
    flat = common.reshape(-1, common.shape[-2] * 3)
    stats = (flat.mean(0), flat.std(0) + 1e-6)
    cls = train_classifier(train, meta["num_joints"], cfg.model.pjd_joints, steps=40 if quick else 400,
                           pos_scale=d.pos_scale)
    feet = tuple(pairs[0].skeleton.foot_joints())
    key = jax.random.key(0)
    methods = {f"Ours (cross-space, step {meta['restored_step']})": _model_method(cfg, nets, params, fa)}
    if cfg.model.refiner:
        methods["w/o Motion Refiner (same checkpoint, refiner off)"] = _model_method(cfg, nets, params, fa, False)
    nogan = full_dir + "_nogan"
    if not untrained and os.path.exists(os.path.join(nogan, "interaction_meta.json")):
        gcfg, gnets, gparams, gmeta = restore_run(nogan)
        methods[f"w/o Inter. GAN (step {gmeta['restored_step']})"] = _model_method(gcfg, gnets, gparams, fa)
    if indep_dir:
        icfg, inets, iparams, imeta = restore_run(indep_dir)
        methods[f"Independent characters (same net w/o interaction, step {imeta['restored_step']})"] = \
            _model_method(icfg, inets, iparams, fa)
    methods["Independent characters (interpolation)"] = _interp_method
    methods["Ground truth"] = _gt_method
    rows = {name: evaluate(m, windows, stats, cls[:2], feet, d.pos_scale, key) for name, m in methods.items()}
    rows["Paper, Boxing 'Ours' (different data; reference only)"] = dict(PAPER_BOXING)
    stops = {}
    if windows.get(50):
        stops["Ours"] = stop_stats(cfg, nets, params, fa, windows[50])
        if indep_dir:
            stops["Independent"] = stop_stats(icfg, inets, iparams, fa, windows[50])
    n_win = {L: (len(w["names"]) if w else 0) for L, w in windows.items()}
    note = (f"Data: {data_source or 'default source'}; {len(pairs)} "
            f"{'CONSTRUCTED pairs (single-person clips paired by us, not real two-person captures)' if constructed else 'real pairs'}"
            f"; test windows per length {n_win}; classifier accuracy {cls[2]:.2f}."
            + (" UNTRAINED networks (a few steps only)." if untrained else ""))
    table = format_table(rows, note)
    if stops:
        table += "\n\nRollout until both characters are within the keypose threshold (50-frame test gaps): " + \
            "; ".join(f"{k}: {v['reached']:.0%} reached within {v['max_frames']} frames, mean {v['mean_frames']:.0f} "
                      f"frames (true gap {v['true_gap']}, threshold {v['threshold_m']} m, median closest approach "
                      f"{v['median_closest_m']:.2f} m)" for k, v in stops.items())
    os.makedirs(results_dir, exist_ok=True)
    with open(os.path.join(results_dir, "interaction_table.md"), "w") as f:
        f.write(table + "\n")
    out = dict(markdown="### Interaction in-betweening (paper Table 1 layout)\n\n" + table, rows=rows, note=note,
               stops=stops, untrained=untrained, constructed=constructed, windows=n_win,
               seconds=time.time() - t0, full_run=None if untrained else full_dir, indep_run=indep_dir)
    with open(os.path.join(results_dir, "interaction_table.json"), "w") as f:
        json.dump(out, f, indent=1)
    print(table)
    return out


if __name__ == "__main__":
    import argparse
    ap = argparse.ArgumentParser()
    ap.add_argument("--source")
    ap.add_argument("--results-dir", default="results")
    ap.add_argument("--ckpt-dir")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    run(a.source, a.results_dir, a.ckpt_dir, a.quick)
