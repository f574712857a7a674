"""Speed section of ``make bench``: compiled JAX against PyTorch (eager and ``torch.compile``), in one process.

    run(source=None, results_dir="results", reps=10, quick=False, torch_ref=None, torch_skip=None,
        torch_cae=None) -> dict

``torch_ref``: the PyTorch S-CVAE reference module (:mod:`inbetween_jax.evaluation.torch_ref.scvae`:
``available()``, ``make_step(..., compile_backend=None)``) or None (its cells say skipped, with ``torch_skip`` as
the reason, default "torch not installed"); ``torch_cae``: the CAE reference (default: the one beside
``torch_ref``).  Front end: ``inbetween speed`` (:mod:`inbetween_jax.cli.speed_cmd`; ``make bench``'s last section).

Rows (medians of ``--reps`` timed calls, at least 5 for the training steps; every call blocked on its result):

* Training steps, each timed side by side in rounds (every variant once per round, rotating order, so a change
  in machine load hits all alike): JAX's jitted, buffer-donating step (``run_training``'s) against the PyTorch
  reference in eager mode and under ``torch.compile`` (backends :data:`TORCH_BACKENDS`, each compiled in its
  first call, which is timed; one that takes over :data:`COMPILE_TIMEOUT_S` s or fails counts as not
  compiling).  S-CVAE: paper and half (``cpu``) widths, batch 32, a 50-frame transition (L = 51), generators and
  discriminators.  CAE: the ``improved`` and ``cpu`` presets (``--quick``: ``improved``), one real batch of the
  preset's training clips after the gap-length curriculum.  json: ``jax_step_ms``, ``torch_step_ms``,
  ``torch_compile_step_ms`` / ``_backend`` / ``_s`` and ``torch_compile_tries`` per width and preset.
* S-CVAE inference: 10 diverse 50-frame transitions of one keyframe pair in one vmapped call (ms), and the
  batched throughput (transitions/s) for 64 pairs x 10 samples.
* CAE inference (paper widths) on a 1927-frame sequence, ms per frame (paper: 0.3 ms/frame on a GPU).
* Interaction network, one 10-frame autoregressive step for both characters with the refiner, ms.
* Compile time of each jitted function: cold (persistent cache off) and from the persistent cache.
* Achieved FLOP/s of the S-CVAE step: matmul FLOPs of its jaxpr (scan bodies times their length, see
  :mod:`inbetween_jax.profiling`) over its median time, against the measured float32 matmul peak.

All inputs are real motion from the source (embedded CMU by default); the networks have random weights
(speed does not depend on them).  Writes ``speed.md`` / ``speed.json`` under ``--results``.
"""
from __future__ import annotations

import dataclasses
import json
import os
import platform
import tempfile
import time

import numpy as np

from inbetween_jax.evaluation.speed_timing import (COMPILE_TIMEOUT_S, TORCH_BACKENDS,  # noqa: F401
                                                   compare_steps as _compare_steps, compile_pair as _compile_pair,
                                                   first_call_s as _first_call_s, side_by_side as _side_by_side)
from inbetween_jax.malloc import MARK_ENV as MALLOC_MARK

__all__ = ["run", "markdown", "scvae_rows", "scvae_step_setup", "cae_rows", "cae_train_rows", "interaction_rows",
           "TORCH_BACKENDS"]


def scvae_step_setup(variant, data, stats, batch=32, n_trans=50, overrides=()):
    """The speed section's S-CVAE training step of one width: ``(cfg, numpy batch, step_fn, init_fn, length)`` on
    ``batch`` real windows of ``data`` (drawn with seed 0) with ``n_trans``-frame transitions (``overrides``:
    ``key=value`` strings applied to the preset, e.g. ``model.remat=``)."""
    from inbetween_jax.models.scvae import train as scvae_train
    from inbetween_jax.models.scvae.config import get_config
    from inbetween_jax.train.config import apply_overrides
    length = n_trans + 1
    cfg = apply_overrides(get_config(variant), list(overrides))
    cfg = dataclasses.replace(cfg, data=dataclasses.replace(cfg.data, trans_max=n_trans))
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(data), batch)
    starts = rng.integers(0, data.q.shape[1] - length, batch)
    np_batch = scvae_train.make_batch(data, idx, starts, length, length)
    return (cfg, np_batch, scvae_train.make_train_step(cfg, data.parents, length),
            scvae_train.make_init_fn(cfg, stats, data.q.shape[2]), length)


def _train_step_row(variant, win, data, stats, reps, torch_ref=None, batch=32, n_trans=50):
    """JAX and PyTorch-eager S-CVAE training steps of one width on the same real batch."""
    import jax
    import jax.numpy as jnp

    from inbetween_jax.profiling import matmul_flops
    from inbetween_jax.train.loop import make_step_fn, strongly_typed

    cfg, np_batch, step_fn, init_fn, length = scvae_step_setup(variant, data, stats, batch, n_trans)
    j = data.q.shape[2]
    jit_step = make_step_fn(step_fn, jax.random.key(1))
    state = jax.tree.map(strongly_typed, init_fn(jax.random.key(0)))
    dev_batch = jax.tree.map(jnp.asarray, np_batch)
    i0 = np.int32(0)
    out = {"variant": variant, "batch": batch, "n_trans": n_trans,
           "gen_params": int(sum(x.size for x in jax.tree.leaves(state["params"])))}
    out["compile_train"] = _compile_pair(jit_step, state, dev_batch, i0)
    flops = matmul_flops(lambda s, b: step_fn(s, b, jax.random.key(0)), state, dev_batch)
    holder = {"s": state}

    def run_step():
        holder["s"], m = jit_step(holder["s"], dev_batch, i0)
        return m["loss"]

    make_torch = None
    if torch_ref is not None and torch_ref.available():
        def make_torch(backend):
            return torch_ref.make_step(cfg, j, data.parents, stats, np_batch, length, seed=0, compile_backend=backend)
        out["torch_threads"] = int(torch_ref.torch.get_num_threads())
    _compare_steps(out, run_step, make_torch, reps)
    for k in ("jax", "torch", "torch_compile"):
        if f"{k}_step_ms" in out:
            out[f"{k}_frames_s"] = batch * n_trans / (out[f"{k}_step_ms"] / 1e3)
    out["step_gflop"] = flops / 1e9
    out["jax_gflops"] = flops / (out["jax_step_ms"] / 1e3) / 1e9
    return out, cfg, holder["s"]


def scvae_rows(source, reps, quick, widths=("paper", "cpu"), torch_ref=None):
    import jax
    import jax.numpy as jnp

    from inbetween_jax.data import load_dataset
    from inbetween_jax.models.scvae import model as scvae
    from inbetween_jax.models.scvae.features import TrainData, compute_stats
    from inbetween_jax.profiling import matmul_flops, median_ms, time_calls

    n_trans = 50
    length = n_trans + 1
    win = load_dataset(source, "benchmark")          # 65-frame windows: room for L = 51
    data = TrainData.from_windows(win)
    stats = compute_stats(win)
    rows = {}
    for variant in widths:
        rows[variant], cfg_v, state_v = _train_step_row(variant, win, data, stats, reps, torch_ref)
        if variant == widths[0]:
            cfg, state = cfg_v, state_v
    out = dict(rows[widths[0]], num_joints=int(data.q.shape[2]), widths=rows)
    # inference: one pair x 10 samples, and 64 pairs x 10 samples
    params, st = state["params"], state["stats"]
    sample = jax.jit(lambda p, st, s, t, k: scvae.sample(p, cfg.model, st, s, t, length, k, length)["out"])

    def keyframes(b):
        k0, k1 = 0, length
        pick = lambda x, f: jnp.asarray(x[:b, f])
        return ({"q": pick(win.local_quats, k0), "r": pick(win.root_pos, k0), "c": pick(win.contacts, k0)},
                {"q": pick(win.local_quats, k1), "r": pick(win.root_pos, k1), "c": pick(win.contacts, k1)})

    keys = jax.random.split(jax.random.key(2), 10)
    s1, t1 = keyframes(1)
    out["compile_infer"] = _compile_pair(sample, params, st, s1, t1, keys)
    out["infer_10_gflop"] = matmul_flops(lambda p: sample(p, st, s1, t1, keys), params) / 1e9
    out["infer_10_ms"] = median_ms(time_calls(lambda: sample(params, st, s1, t1, keys), reps=reps * 2, warmup=2))
    nb = 16 if quick else 64
    sb, tb = keyframes(min(nb, len(win)))
    tb_ms = median_ms(time_calls(lambda: sample(params, st, sb, tb, keys), reps=max(3, reps // 2), warmup=1))
    out["infer_batch"] = int(sb["q"].shape[0]) * 10
    out["infer_transitions_s"] = out["infer_batch"] / (tb_ms / 1e3)
    return out


def cae_rows(source, reps, quick):
    import jax
    import jax.numpy as jnp

    from inbetween_jax.data import load_motions
    from inbetween_jax.models.cae import model as cae
    from inbetween_jax.models.cae.config import get_config
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.profiling import median_ms, time_calls

    frames = 1927
    motions = load_motions(source, "train") + load_motions(source, "test")
    feats = np.concatenate([body_frame_features(m).features for m in motions])
    x = np.tile(feats, (int(np.ceil(frames / len(feats))), 1))[:frames]          # real frames, repeated if short
    x = ((x - x.mean(0)) / (x.std(0) + 1e-3)).T[None].astype(np.float32)      # (1, D, 1927)
    cfg = get_config("paper")
    params = cae.init_params(jax.random.key(0), cfg, x.shape[1])
    fwd = jax.jit(lambda p, v: cae.apply(p, v, cfg))
    xj = jnp.asarray(x)
    out = {"frames": frames, "rows": int(x.shape[1]), "params": int(sum(a.size for a in jax.tree.leaves(params)))}
    out["compile"] = _compile_pair(fwd, params, xj)
    ms = median_ms(time_calls(lambda: fwd(params, xj), reps=reps, warmup=2))
    out["ms"], out["ms_per_frame"] = ms, ms / frames
    return out


def cae_train_rows(source, reps, presets=("improved", "cpu"), torch_cae=None) -> dict:
    """CAE training steps of ``presets`` (``inbetween train cae``'s jitted step: mask draw, forward, backward,
    Adam) on one real batch of its training clips, against the ``torch_cae`` reference (eager and compiled).
    Returns {preset: row}."""
    import jax

    from inbetween_jax.models.cae import train as cae_train
    from inbetween_jax.models.cae.config import get_config
    from inbetween_jax.train.loop import make_step_fn, strongly_typed

    rows = {}
    for preset in presets:
        cfg = get_config(preset)
        tr = cae_train.make_training(cfg, cae_train.load_data(cfg, source, "train"))
        batch = tr.batch_fn(cfg.train.num_steps // 2, jax.random.key(2))      # after the gap-length curriculum
        state = jax.tree.map(strongly_typed, tr.init_fn(jax.random.key(0)))
        params0 = jax.tree.map(np.asarray, state["params"])                   # before the donated steps
        jit_step = make_step_fn(tr.step_fn, jax.random.key(1))
        i0 = np.int32(0)
        out = {"preset": preset, "batch": int(batch["x"].shape[0]), "rows": int(batch["x"].shape[1]),
               "frames": int(batch["x"].shape[2]), "channels": list(cfg.model.channels),
               "params": int(sum(a.size for a in jax.tree.leaves(params0)))}
        dev = jax.tree.map(jax.numpy.asarray, batch)
        out["compile_train"] = _compile_pair(jit_step, state, dev, i0)
        holder = {"s": state}

        def run_step():
            holder["s"], m = jit_step(holder["s"], dev, i0)
            return m["loss"]

        make_torch = None
        if torch_cae is not None and torch_cae.available():
            def make_torch(backend, cfg=cfg, batch=batch, params0=params0):
                return torch_cae.make_step(cfg, params0, batch["x"], batch["mu"], batch["matched"], backend)
        _compare_steps(out, run_step, make_torch, reps)
        rows[preset] = out
    return rows


def interaction_rows(source, reps, quick):
    import jax
    import jax.numpy as jnp

    from inbetween_jax.data import load_motions
    from inbetween_jax.models.interaction import model as I
    from inbetween_jax.models.interaction.config import get_config
    from inbetween_jax.models.interaction.features import (keyframe_sample, scale_positions, skeleton_forward_axis,
                                                           world_joint_features)
    from inbetween_jax.profiling import median_ms, time_calls

    cfg = get_config("cpu")
    motions = load_motions(source, "train")
    m = max(motions, key=lambda mm: mm.num_frames)
    feats = world_joint_features(m)                               # (T, J, 9) real frames
    fa = skeleton_forward_axis(m.skeleton)
    t_in = cfg.data.n_input
    pair = np.stack([feats, feats[::-1].copy()])                   # two real performances, same length
    ks = keyframe_sample(pair, 0, t_in, min(len(feats) - 1, t_in + 30), fa)
    ks = {k: np.asarray(v, np.float32)[None] for k, v in scale_positions(ks, 0.01).items()}
    win, key, eye, zero = (jnp.asarray(ks[k]) for k in ("x", "keypose", "rel_R", "rel_t"))
    params = I.init_params(jax.random.key(0), cfg, feats.shape[1])
    fa_j = jnp.asarray(fa, jnp.float32)

    def one_step(p, w, kp, k):
        o = I.generator_step(p["gen"], w, kp, eye, zero, k, cfg, fa_j)
        return I.refine(p["ref"], o["pred"], cfg) if cfg.model.refiner else o["pred"]

    step = jax.jit(one_step)
    k0 = jax.random.key(3)
    out = {"num_joints": int(feats.shape[1]), "n_input": t_in, "n_pred": cfg.data.n_pred}
    out["compile"] = _compile_pair(step, params, win, key, k0)
    out["ms"] = median_ms(time_calls(lambda: step(params, win, key, k0), reps=reps * 2, warmup=2))
    return out


def _fmt_pair(p):
    return f"{p[0]:.1f} / {p[1]:.1f}"


def _step_cells(w: dict, skip: str) -> str:
    """The JAX / eager / compiled / ratio cells of one training-step row (ms per step)."""
    if "torch_step_ms" not in w:
        return f"{w['jax_step_ms']:.0f} ms | {skip} | {skip} | - | - |"
    if "torch_compile_step_ms" in w:
        comp = (f"{w['torch_compile_step_ms']:.0f} ms ({w['torch_compile_backend']}, "
                f"{w['torch_compile_s']:.0f} s)")
        comp_ratio = f"{w['torch_compile_step_ms'] / w['jax_step_ms']:.2f}x"
    else:
        comp, comp_ratio = "did not compile", "-"
    return (f"{w['jax_step_ms']:.0f} ms | {w['torch_step_ms']:.0f} ms | {comp} | "
            f"{w['torch_step_ms'] / w['jax_step_ms']:.2f}x | {comp_ratio} |")


def markdown(r) -> str:
    s, c, i = r["scvae"], r["cae"], r["interaction"]
    lines = [f"## Speed (JAX {r['jax']}, {r['device']}, {r['cpus']} cores, malloc {r.get('malloc', 'system')}; "
             "medians after warm-up, one process)", "",
             f"Matmul peak (float32 1024^3, measured): {r['peak_gflops']:.1f} GFLOP/s.", "",
             "Training steps, timed side by side (each round calls every variant once): JAX's jitted step against "
             "PyTorch eager and `torch.compile` (the first backend of "
             f"{', '.join(TORCH_BACKENDS)} that compiled within {COMPILE_TIMEOUT_S} s; its first call, compile + one "
             "step, in brackets). Ratios: PyTorch's time over JAX's (> 1: JAX is faster).", "",
             "| train step | JAX | PyTorch eager | PyTorch compiled | eager / JAX | compiled / JAX |",
             "|---|---|---|---|---|---|"]
    skip = f"{r.get('torch_skip') or 'torch not installed'}"
    for name, w in s["widths"].items():
        lines.append(f"| S-CVAE, {name} widths ({w['gen_params'] / 1e6:.1f} M generator params), batch {w['batch']}, "
                     f"{w['n_trans']}-frame transition | " + _step_cells(w, skip))
    for name, w in c.get("train", {}).items():
        lines.append(f"| CAE `{name}` (channels {','.join(map(str, w['channels']))}, {w['params'] / 1e3:.0f} k params), "
                     f"batch {w['batch']} x {w['rows']} x {w['frames']} | " + _step_cells(w, skip))
    lines += ["", "| row | JAX | target |", "|---|---|---|"]
    bound = 1e3 * s["infer_10_gflop"] / r["peak_gflops"]
    lines += ["| S-CVAE train step against PyTorch eager | first table | JAX >= 2x |",
              f"| S-CVAE inference, 10 samples x 1 pair | {s['infer_10_ms']:.1f} ms ({s['infer_10_gflop']:.1f} GFLOP: "
              f">= {bound:.0f} ms at the matmul peak) | <= 20 ms |",
              f"| S-CVAE inference, {s['infer_batch']} transitions per call | {s['infer_transitions_s']:.0f} "
              "transitions/s | |",
              f"| CAE inference, {c['frames']} frames (paper widths) | {c['ms_per_frame']:.3f} ms/frame "
              f"({c['ms']:.0f} ms) | < 0.3 ms/frame (paper, GPU) |",
              f"| Interaction net, 10 frames x 2 characters (+ refiner) | {i['ms']:.2f} ms | <= 5 ms "
              "(paper: 125 ms) |",
              f"| S-CVAE step (paper widths) achieved FLOP/s | {s['jax_gflops']:.1f} GFLOP/s = "
              f"{100 * s['jax_gflops'] / r['peak_gflops']:.0f} % of peak ({s['step_gflop']:.1f} GFLOP/step) | |",
              "", "Compile times, s (cold with the persistent cache off / served from the persistent cache); "
              "target <= 30 s:", "",
              "| function | cold / cached |", "|---|---|",
              *[f"| S-CVAE train step, {n} widths | {_fmt_pair(w['compile_train'])} |" for n, w in s["widths"].items()],
              f"| S-CVAE vmapped rollout (10 samples) | {_fmt_pair(s['compile_infer'])} |",
              *[f"| CAE train step, `{n}` | {_fmt_pair(w['compile_train'])} |" for n, w in c.get("train", {}).items()],
              f"| CAE forward, 1927 frames | {_fmt_pair(c['compile'])} |",
              f"| Interaction step | {_fmt_pair(i['compile'])} |"]
    if "torch_threads" in s:
        lines += ["", f"PyTorch {r.get('torch', '?')} with {s['torch_threads']} threads."]
    return "\n".join(lines) + "\n"


def _cae_reference(scvae_ref):
    """The CAE reference beside ``scvae_ref``: the package's :mod:`.torch_ref.cae` for the package's S-CVAE
    reference, ``cae.py`` in the folder of another reference file, else None."""
    if scvae_ref is None:
        return None
    if getattr(scvae_ref, "__name__", "") == "inbetween_jax.evaluation.torch_ref.scvae":
        from inbetween_jax.evaluation.torch_ref import cae
        return cae
    path = os.path.join(os.path.dirname(os.path.abspath(getattr(scvae_ref, "__file__", None) or ".")), "cae.py")
    if not os.path.isfile(path):
        return None
    import importlib.util
    spec = importlib.util.spec_from_file_location("inbetween_torch_cae", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run(source=None, results_dir="results", reps=10, quick=False, torch_ref=None, torch_skip=None,
        torch_cae=None) -> dict:
    """All speed rows; writes ``speed.md`` / ``speed.json`` under ``results_dir`` and returns the record.
    torch_ref: the PyTorch-eager S-CVAE reference module, or None; torch_skip: why there is none (the skipped
    rows say it; default "torch not installed"); torch_cae: the CAE reference (default: the one beside
    ``torch_ref``, :func:`_cae_reference`)."""
    import jax

    from inbetween_jax.data import resolve_source
    from inbetween_jax.profiling import matmul_peak_flops
    from inbetween_jax.train.loop import enable_compilation_cache

    enable_compilation_cache(tempfile.mkdtemp(prefix="jax-cache-bench-"))   # a fresh cache: honest cold numbers
    src = resolve_source(source)
    t0 = time.time()
    r = {"source": src, "jax": jax.__version__, "device": str(jax.devices()[0].device_kind),
         "platform": platform.processor() or platform.machine(), "cpus": os.cpu_count(), "reps": reps,
         "malloc": os.path.basename(os.environ.get(MALLOC_MARK, "")) or "system"}     # inbetween_jax.malloc
    if torch_ref is not None and torch_ref.available():
        r["torch"] = torch_ref.torch.__version__
    elif torch_skip or torch_ref is not None:
        r["torch_skip"] = torch_skip if torch_ref is None else "torch not installed"
    r["peak_gflops"] = matmul_peak_flops() / 1e9
    r["scvae"] = scvae_rows(src, reps, quick, torch_ref=torch_ref)
    r["cae"] = cae_rows(src, reps, quick)
    r["cae"]["train"] = cae_train_rows(src, reps, ("improved",) if quick else ("improved", "cpu"),
                                       torch_cae if torch_cae is not None else _cae_reference(torch_ref))
    r["interaction"] = interaction_rows(src, reps, quick)
    r["peak_gflops_after"] = matmul_peak_flops() / 1e9
    r["wall_s"] = time.time() - t0
    r["markdown"] = markdown(r)
    os.makedirs(results_dir, exist_ok=True)
    with open(os.path.join(results_dir, "speed.json"), "w") as fh:
        json.dump(r, fh, indent=1, default=float)
    with open(os.path.join(results_dir, "speed.md"), "w") as fh:
        fh.write(r["markdown"])
    return r
