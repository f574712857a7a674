"""Two-character in-betweening benchmark rows in the layout of the interaction paper's Table 1.

``run(source, results_dir, run_dir, quick)`` evaluates, on the test split of the paired data (protocol:
:mod:`inbetween_jax.evaluation.interaction`): the cross-space model (``run_dir``), the independent-characters
baseline (the same network trained with ``model.interaction=false model.gan=false``, found next to
``run_dir``: ``<run_dir>_indep``, a ``_full`` -> ``_indep`` sibling, or ``run_dir/indep``) and per-character
interpolation, plus ground truth for the interaction score. Ablations: the same checkpoint with the refiner
switched off (on, for runs that leave it off), ``<run_dir>_nogan`` (trained with ``model.gan=false``) when
present, for an ensemble (``model.members`` > 1) its first member alone, and for a run with a motion bank
(:mod:`.bank`) the network without it, the bank's in-between alone and interpolation with the bank's texture
(neither of the last two uses the network). Without a trained run the
benchmark is skipped (the markdown says why and how to train one).
"""
from __future__ import annotations

import dataclasses
import functools
import json
import os
import time

import numpy as np

TITLE = "### Interaction in-betweening (paper Table 1 layout)"
TRAIN_HINT = "inbetween train interaction --preset cpu --run-dir runs/interaction"
# Steps of the interaction classifier, in the quick and the full bench alike: the score is only comparable when
# every table measures with the same classifier.  The quick bench used 40 steps until the ninth round; that
# classifier scored the damped rollouts of the shipped model far closer to ground truth than this one does
# (docs/results/interaction.md, ninth round, `experiments/interaction_score_probe.py --steps 40`).
CLASSIFIER_STEPS = 400
# With a guessed gap and ``model.bank_guessed``, the network rolls out at least this many frames to find the
# gap it takes (twice the longest gap the bench scores L2P on); only the frames asked for are kept.
ARRIVAL_HORIZON = 100


def _has_run(path) -> bool:
    from inbetween_jax.train.run import RunError, load_run
    try:
        return load_run(path).model == "interaction"
    except RunError:
        return False


def _find_runs(run_dir):
    """-> (full run folder, independent-characters run folder or None)."""
    run_dir = os.path.normpath(run_dir)
    if os.path.basename(run_dir) == "checkpoints":
        run_dir = os.path.dirname(run_dir)
    if _has_run(run_dir):
        full = run_dir
        cands = [run_dir + "_indep", run_dir.replace("_full", "_indep"), os.path.join(run_dir, "indep")]
    else:
        full = os.path.join(run_dir, "full")
        cands = [os.path.join(run_dir, "indep")]
    indep = next((c for c in cands if c != full and _has_run(c)), None)
    return full, indep


def _restore(path):
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.train.run import load_run
    return load(load_run(path))


def _model_method(trained, use_refiner=None, gap="true", latent_scale=None, use_bank=True):
    """Windows -> (S, B, 2, steps * l, J, 9) rollouts of ``trained`` (no early stop).

    ``gap`` is what a timing-conditioned model (``model.tta`` / ``model.residual``) is told about the gap:
    ``"true"`` -- the window's own transition length L (whatever the rollout length, so the stop-rule rollout of
    2 L frames still aims at frame L + 1); ``"guess"`` -- :func:`~inbetween_jax.evaluation.interaction.guess_gap_length`,
    the same guess the guessed-length interpolation baseline uses (flagged models, ``data.tta_guess``, are
    told that it is a guess).  A run with a motion bank (:mod:`.bank`) gets its in-between and texture when told
    the true gap, unless ``use_bank`` is false.  With a guessed gap the network runs alone (the bank's windows
    are warped to arrive at the gap's end, and on the validation take its blend at a guessed gap raised L2P at
    50 frames from 0.943x to 0.970x the guessed-length interpolation's), unless ``model.bank_guessed``: then the
    network rolls out at least :data:`ARRIVAL_HORIZON` frames, the bank's in-between is blended in over the gap
    that rollout takes (the frames before it first meets the stop rule's threshold, :func:`~.bank.arrival_gaps`;
    no true gap is used; no texture: on the validation take it cost 2 % of L2P at 30 frames with a guessed gap,
    nothing with the true one) and the frames asked for are kept."""
    import jax
    from inbetween_jax.evaluation.interaction import N_INPUT, guess_gap_length
    from inbetween_jax.models.interaction.bank import apply_bank, arrival_gaps, ease_into_keypose, foot_indices
    from inbetween_jax.models.interaction.model import sample_rollouts
    cfg, fa = trained.cfg, trained.forward_axis.astype(np.float32)
    feet = foot_indices(trained.skeleton)
    if gap not in ("true", "guess"):
        raise ValueError(f"gap must be 'true' or 'guess', not {gap!r}")
    cache, l = {}, cfg.data.n_pred

    def rolled(steps, samples):
        if (steps, samples) not in cache:
            cache[(steps, samples)] = jax.jit(lambda p, w, kp, R, t, g, k: sample_rollouts(
                p, w, kp, R, t, k, cfg, fa, steps, samples, threshold=-1.0, use_refiner=use_refiner, gap=g,
                latent_scale=latent_scale, gap_known=gap == "true")[0])
        return cache[(steps, samples)]

    def method(b, steps, samples, key):
        B, L = b["x"].shape[0], b["x"].shape[2] - N_INPUT - 1
        ctx = b["x"][:, :, :N_INPUT]
        g = np.full(B, L, np.float32) if gap == "true" else guess_gap_length(b).astype(np.float32)
        banked = use_bank and trained.bank is not None and (gap == "true" or cfg.model.bank_guessed)
        long = max(steps, -(-ARRIVAL_HORIZON // l)) if banked and gap == "guess" else steps
        out = np.array(rolled(long, samples)(trained.params, ctx, b["keypose"], b["rel_R"], b["rel_t"], g, key))
        if gap == "true":            # the known gap: bank, then the last frames eased onto the keypose
            if banked:
                out = apply_bank(trained.bank, cfg.model, out, ctx, b["keypose"], g, feet, (b["rel_R"], b["rel_t"]))
            if trained.gate is not None and cfg.model.ood_gate:     # toward interpolation (.gate)
                from inbetween_jax.models.interaction.gate import gate_rollouts
                out = gate_rollouts(trained.gate, out, ctx, b["keypose"], g, **trained.gate_kwargs())[0]
            return ease_into_keypose(out, b["keypose"], g, cfg.model.ease_frames) if cfg.model.ease_frames else out
        if not banked:
            return out
        top, blend_only = trained.bank.max_gap(N_INPUT), dataclasses.replace(cfg.model, texture_sigma=0.0)
        for s in range(len(out)):                                   # each sample over the gap it takes itself
            arrive = arrival_gaps(out[s], b["keypose"], cfg.model.stop_threshold, cfg.data.pos_scale)
            ok = np.flatnonzero(arrive <= top)                      # longer than any bank window: network alone
            out[s:s + 1, ok] = apply_bank(trained.bank, blend_only, out[s:s + 1, ok], ctx[ok], b["keypose"][ok],
                                          arrive[ok], feet, (b["rel_R"][ok], b["rel_t"][ok]))
        return out[:, :, :, :steps * l]
    return method


def _bank_baselines(trained) -> dict:
    """Rows that split a bank run's gain into network and bank: the bank's in-between alone and interpolation
    with the bank's texture (neither uses the network)."""
    from inbetween_jax.evaluation.interaction import N_INPUT, interpolation_method
    from inbetween_jax.models.interaction.bank import apply_bank, foot_indices
    m, rows = trained.cfg.model, {}
    feet = foot_indices(trained.skeleton)

    def on_interpolation(model_cfg):
        def method(b, steps, samples, key):
            L = b["x"].shape[2] - N_INPUT - 1
            return apply_bank(trained.bank, model_cfg, interpolation_method(b, steps, samples, key),
                              b["x"][:, :, :N_INPUT], b["keypose"], np.full(len(b["x"]), L), feet,
                              (b["rel_R"], b["rel_t"]))
        return method
    if m.bank_k > 0 and m.bank_weight > 0:
        rows[f"Motion bank alone (mean of {m.bank_k} nearest, warped; no network)"] = (
            "bank", on_interpolation(dataclasses.replace(m, bank_weight=1.0, texture_sigma=0.0)))
    if m.texture_sigma > 0:
        rows[f"Interpolation + motion texture (sigma {m.texture_sigma:g}; no network)"] = (
            "bank", on_interpolation(dataclasses.replace(m, bank_k=0)))
    return rows


def member(trained, index: int = 0):
    """Network ``index`` of an ensemble (``model.members`` > 1) as a single-network model (same checkpoint)."""
    import jax
    cfg = dataclasses.replace(trained.cfg, model=dataclasses.replace(trained.cfg.model, members=1))
    return dataclasses.replace(trained, cfg=cfg, params=jax.tree.map(lambda a: a[index], trained.params))


def stop_stats(trained, b) -> dict:
    """Inference as in the paper: roll out until both characters are within ``model.stop_threshold`` of their
    keyposes (cap ``model.max_frames``).  b: eval windows.  -> reached fraction, mean frames, true gap."""
    import jax
    from inbetween_jax.evaluation.interaction import N_INPUT
    from inbetween_jax.models.interaction.model import keypose_distance, rollout
    cfg, fa = trained.cfg, trained.forward_axis.astype(np.float32)
    steps = cfg.model.max_frames // cfg.data.n_pred
    l = cfg.data.n_pred
    frames, length = jax.jit(lambda p: rollout(p, b["x"][:, :, :N_INPUT], b["keypose"], b["rel_R"], b["rel_t"],
                                               jax.random.key(0), cfg, fa, steps))(trained.params)
    length = np.asarray(length)
    d = np.stack([np.asarray(keypose_distance(frames[:, :, l * k + l - 1], b["keypose"])).max(1)
                  for k in range(steps)], 1)                                  # (B, steps), metres
    return dict(reached=float(np.mean(length < steps * l)), mean_frames=float(length.mean()),
                true_gap=int(b["x"].shape[2] - N_INPUT - 1), threshold_m=cfg.model.stop_threshold,
                max_frames=cfg.model.max_frames, median_closest_m=float(np.median(d.min(1))))


def _skipped(why: str) -> dict:
    return {"markdown": f"{TITLE}\n\nSkipped: {why}. Train one with `{TRAIN_HINT}`.", "rows": [], "skipped": why}


def has_real_pairs(source) -> bool:
    from inbetween_jax.models.interaction.data import find_pair_files
    return bool(source) and source != "embedded" and os.path.isdir(source) and bool(find_pair_files(source))


def run(source, results_dir: str, run_dir, quick: bool = False) -> dict:
    """Evaluate and write ``results_dir/interaction_table.{md,json}``; returns ``{"markdown", "rows", ...}``.

    Without a trained run the table is still made when ``source`` holds real pairs: the baselines
    (interpolation with the true / a guessed gap length, hold last frame) and ground truth."""
    full_dir = indep_dir = None
    if run_dir is not None:
        full_dir, indep_dir = _find_runs(run_dir)
    trained = _restore(full_dir) if full_dir and _has_run(full_dir) else None
    if trained is None and not has_real_pairs(source):
        return _skipped("no interaction run folder given" if run_dir is None
                        else f"{run_dir} holds no trained interaction run")
    import jax

    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.evaluation.tables import flat_rows, markdown_table
    from inbetween_jax.models.interaction.config import get_config
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    t0 = time.time()
    cfg = trained.cfg if trained is not None else get_config()
    d = cfg.data
    data_source = source
    if trained is not None:
        train_source = (_load_run_data(full_dir) or {}).get("source")
        data_source = train_source if source is None else source
    pairs = load_pairs(data_source, d.pair_distance)
    if trained is not None and pairs[0].feats.shape[2] != trained.num_joints:   # trained on another skeleton
        data_source = train_source
        pairs = load_pairs(data_source, d.pair_distance)
    train, test = split_pairs(pairs, "train", d.split), split_pairs(pairs, "test", d.split)
    constructed = any(p.constructed for p in pairs)
    shown = (data_source or "default source") if data_source in (source, "embedded", "cmu") else \
        f"the run's training data ({os.path.basename(os.path.normpath(str(data_source)))})"   # not a trainer's path
    windows = proto.table1_windows(test, d.pos_scale, 24 if quick else 128)
    stats = proto.l2p_stats(train, d.pos_scale)   # the protocol's fixed key range: one scale for every run
    J = pairs[0].feats.shape[2]
    cls = proto.train_classifier(train, J, cfg.model.pjd_joints, steps=CLASSIFIER_STEPS, pos_scale=d.pos_scale)
    feet = tuple(pairs[0].skeleton.foot_joints())
    key = jax.random.key(0)
    methods, stop_rule, notes = {}, {}, []
    indep = _restore(indep_dir) if indep_dir else None
    if trained is not None:
        M = cfg.model.members
        ours = f"Ours (cross-space, step {trained.step})" if M == 1 else \
            f"Ours (cross-space, mean of {M} members, step {trained.step})"
        methods[ours] = ("interaction", _model_method(trained))
        stop_rule[ours] = methods[ours][1]
        if M > 1:
            methods["Ours, its first member alone (same checkpoint)"] = ("interaction",
                                                                         _model_method(member(trained)))
        if cfg.model.tta or cfg.model.residual:
            banked = trained.bank is not None and cfg.model.bank_guessed
            guessed = f"Ours, gap length guessed (step {trained.step}" + (
                "; the bank's in-between over the rollout's own gap)" if banked else ")")
            methods[guessed] = ("interaction", _model_method(trained, gap="guess"))
            stop_rule[guessed] = methods[guessed][1]
            if banked:
                methods["Ours, gap length guessed, the network alone"] = ("interaction", _model_method(
                    trained, gap="guess", use_bank=False))
        if cfg.model.refiner:
            methods["w/o Motion Refiner (same checkpoint, refiner off)"] = ("interaction",
                                                                          _model_method(trained, False))
        else:   # improved: the refiner is trained but off at inference (chosen on the validation take)
            methods["with Motion Refiner (same checkpoint, refiner on)"] = ("interaction",
                                                                          _model_method(trained, True))
        if trained.bank is not None:
            methods["w/o motion bank (same checkpoint, the network alone)"] = ("interaction",
                                                                             _model_method(trained, use_bank=False))
            m = cfg.model
            if m.texture_sigma > 0 and m.bank_k > 0 and m.bank_weight > 0:
                plain = dataclasses.replace(trained, cfg=dataclasses.replace(cfg, model=dataclasses.replace(
                    m, texture_sigma=0.0)))
                methods["w/o motion texture (same checkpoint, the bank's in-between blended in)"] = (
                    "interaction", _model_method(plain))
            methods.update(_bank_baselines(trained))
        nogan = full_dir + "_nogan"
        if _has_run(nogan):
            g = _restore(nogan)
            methods[f"w/o Inter. GAN (step {g.step})"] = ("interaction", _model_method(g))
        if indep is not None:
            methods[f"Independent characters (same net w/o interaction, step {indep.step})"] = \
                ("interaction", _model_method(indep))
        if not constructed:
            name = "Ours run on each character independently (partner slot = the character itself)"
            methods[name] = ("interaction", proto.independent_method(methods[ours][1]))
            stop_rule[name] = methods[name][1]
    else:
        notes.append("No trained interaction run: the model rows and the model run on each character "
                     f"independently are skipped (train one with `{TRAIN_HINT} --source {data_source}`).")
    interp = "Independent characters (interpolation)" if constructed else "Interpolation (true gap length)"
    methods[interp] = ("interpolation", proto.interpolation_method)
    if not constructed:
        guess = "Interpolation (guessed gap length)"
        methods[guess] = ("interpolation_guess", proto.guessed_interpolation_method)
        stop_rule[guess] = methods[guess][1]
        methods["Hold last frame"] = ("hold", proto.hold_method)
    methods["Ground truth"] = ("ground_truth", proto.ground_truth_method)
    results = {name: proto.evaluate(m, windows, stats, cls[:2], feet, d.pos_scale, key)
               for name, (_, m) in methods.items()}
    paper_name = "Paper, Boxing 'Ours' (different data; reference only)"
    results[paper_name] = dict(proto.PAPER_BOXING)
    stops = {}
    if trained is not None and windows.get(50):
        stops["Ours"] = stop_stats(trained, windows[50])
        if indep is not None:
            stops["Independent"] = stop_stats(indep, windows[50])
    arrivals = {}
    if not constructed:
        for L in (30, 50):
            if windows.get(L):
                for name, m in stop_rule.items():
                    arrivals[(name, L)] = proto.arrival_stats(m, windows[L], cfg.model.stop_threshold, key,
                                                              d.pos_scale)
    n_win = {L: (len(w["names"]) if w else 0) for L, w in windows.items()}
    kind = ("CONSTRUCTED pairs (single-person clips paired by us, not real two-person captures)" if constructed
            else "REAL two-person capture pairs (split by whole takes: " +
            ", ".join(f"{sp} {[p.name for p in pairs if p.split == sp]}" for sp in ("train", "test")) + ")")
    note = (f"Data: {shown}; {len(pairs)} {kind}; {J} joints at {pairs[0].fps:g} fps; "
            f"test windows per length {n_win}; interaction classifier trained on the training pairs, accuracy "
            f"{cls[2]:.2f}. {proto.GUESS_NOTE} "
            + proto.NPSS_NOTE + (" " + " ".join(notes) if notes else ""))
    table = proto.format_table(results, note)
    if stops:
        table += "\n\nRollout until both characters are within the keypose threshold (50-frame test gaps): " + \
            "; ".join(f"{k}: {v['reached']:.0%} reached within {v['max_frames']} frames, mean {v['mean_frames']:.0f} "
                      f"frames (true gap {v['true_gap']}, threshold {v['threshold_m']} m, median closest approach "
                      f"{v['median_closest_m']:.2f} m)" for k, v in stops.items())
    if arrivals:
        arows = [{"method": n, "true gap": L, "reached within 2x gap": round(v["reached"], 3),
                  "median frames to arrival": v["median_frames"]} for (n, L), v in arrivals.items()]
        table += "\n\n" + markdown_table(arows, ("true gap", "reached within 2x gap", "median frames to arrival"),
                                          keys=("method",), digits=3,
                                          title=f"Stop rule: first frame where both characters are within "
                                                f"{cfg.model.stop_threshold} m (mean joint distance) of their "
                                                "keyposes, rollout of 2 x the true gap")
    data_name = "embedded" if data_source == "embedded" else os.path.basename(os.path.normpath(str(data_source)))
    groups = {name: kind_ for name, (kind_, _) in methods.items()}
    groups[paper_name] = "paper"
    rows = []
    for name, res in results.items():
        model = groups[name]
        rows += flat_rows(proto.long_rows(res), table="interaction_table1", data=data_name, model=model,
                          variant=name if model in ("interaction", "paper", "bank") else "", keys=("frames",))
    for name, s in stops.items():
        rows += flat_rows([{"method": name, "reached": s["reached"], "mean_frames": s["mean_frames"],
                            "median_closest_m": s["median_closest_m"]}], table="interaction_stop", data=data_name,
                          model="interaction", variant=name, keys=())
    for (name, L), v in arrivals.items():
        rows += flat_rows([{"method": name, "frames": L, "reached": v["reached"], "median_frames": v["median_frames"]}],
                          table="interaction_arrival", data=data_name, model=groups[name], variant=name)
    if trained is not None and not constructed:          # the worst case: per-window ratios to interpolation
        from inbetween_jax.models.interaction.samples import bench_rows, per_window_rows, sample_table
        wc, wc_md = per_window_rows(trained, methods[ours][1], windows, data_name)
        sr, sr_md = bench_rows(sample_table(methods[ours][1], windows, stats, cls[:2]), data_name, ours)
        rows += wc + sr
        table += "\n\n" + wc_md + "\n\n" + sr_md
    os.makedirs(results_dir, exist_ok=True)
    with open(os.path.join(results_dir, "interaction_table.md"), "w") as f:
        f.write(table + "\n")
    out = dict(markdown=f"{TITLE}\n\n" + table, rows=rows, results=results, note=note, stops=stops,
               arrivals=[dict(method=n, frames=L, **v) for (n, L), v in arrivals.items()],
               constructed=constructed, windows=n_win, seconds=time.time() - t0, full_run=full_dir,
               indep_run=indep_dir)
    with open(os.path.join(results_dir, "interaction_table.json"), "w") as f:
        json.dump(out, f, indent=1, default=float)
    return out


VAL_LENGTHS = (30, 50)


def val_score(run, source, use_refiner=None, max_windows: int = 64, latent_scale=None) -> float:
    """Checkpoint selection score (lower is better): mean L2P at 30 and 50 frames, true gap, one sample, on
    the validation split of ``source``'s pairs (:func:`~.data.split_pairs`: a held-out training take of real
    pairs, never the test takes), on the L2P scale of the ``fit`` pairs.  use_refiner / latent_scale: None =
    as configured."""
    from inbetween_jax.models.interaction.infer import load
    trained = load(run)
    d = trained.cfg.data
    windows, stats = _val_data(source or run.data.get("source"), d.pair_distance, tuple(d.split), d.pos_scale,
                               max_windows)
    method = _model_method(trained, use_refiner, latent_scale=latent_scale)
    return float(np.mean(windows_l2p(method, windows, stats, d.n_pred)))


def windows_l2p(method, windows, stats, n_pred: int = 10, lengths=VAL_LENGTHS) -> list:
    """L2P of one sample of ``method`` (a bench method: ``(windows, steps, samples, key) -> (S, B, 2, F, J, 9)``)
    on ``windows[L]`` for each L of ``lengths``, the sample drawn with key ``jax.random.key(L)``; stats: the
    L2P normalisation (:func:`~inbetween_jax.evaluation.interaction.l2p_stats`)."""
    import jax

    from inbetween_jax.evaluation.interaction import pair_l2p
    return [pair_l2p(np.asarray(method(windows[L], -(-L // n_pred), 1, jax.random.key(L)))[0, :, :, :L], windows[L],
                     stats) for L in lengths]


@functools.lru_cache(maxsize=2)
def _val_data(source, distance, fractions: tuple, pos_scale, max_windows):
    """(``{L: windows}`` of the validation pairs, L2P stats of the fit pairs), read once per process (checkpoint
    selection scores every checkpoint of a run on the same windows); ValueError when the validation split has
    no window of every length."""
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    pairs = load_pairs(source, distance)
    fit, val = split_pairs(pairs, "fit", fractions), split_pairs(pairs, "val", fractions)
    windows = proto.table1_windows(val, pos_scale, max_windows, VAL_LENGTHS) if val else {}
    if not all(windows.get(L) for L in VAL_LENGTHS):
        raise ValueError(f"{source}: the validation split has no {'/'.join(map(str, VAL_LENGTHS))}-frame window")
    return windows, proto.l2p_stats(fit, pos_scale)


def _load_run_data(path) -> dict:
    from inbetween_jax.train.run import load_run
    return load_run(path).data
