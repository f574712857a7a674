"""Seed sweeps in one program: N seeds of one config share one compiled, ``vmap``-ped training step.

Generic part (any registered model): :func:`train_seeds` takes the model's
:class:`~inbetween_jax.models.spec.Training` (``spec.make_training(cfg, data)``), ``vmap``-s its init over
the seeds' PRNG keys and the training loop's own step body (:func:`inbetween_jax.train.loop.step_body`) over
(state, batch, key), so N seeds cost one compilation and one (batched) step per iteration.  With several
devices the seed axis is split over a mesh (:func:`inbetween_jax.train.make_mesh`).

Seed ``s`` follows :func:`inbetween_jax.train.run_training` exactly: ``key(s)`` splits into init, data and
train keys, step ``i`` uses ``batch_fn(i, fold_in(data_key, i))`` and ``fold_in(train_key, i)``, so a
vmapped seed reproduces the single run of that seed (up to float rounding).

Ablation sweep (:func:`run`, the S-CVAE paper's Table 6 with seed repeats): rows are the full model and the
full model with one ablation switch turned off (:data:`ABLATIONS`); rows change the parameter structure, so
they run one after another.  Every (row, seed) samples transitions of ``frames`` frames between frame
``N_PAST - 1`` and frame ``N_PAST + frames`` of every test window, scored with
:func:`inbetween_jax.evaluation.transition_metrics`; the table shows mean ± std (ddof=1) over seeds.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import time

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.train.ablations import ABLATIONS, DEFAULT_STEPS
from inbetween_jax.train.loop import run_keys

__all__ = ["ABLATIONS", "COLUMNS", "DEFAULT_STEPS", "N_PAST", "seed_keys", "stack_batches", "make_vmapped",
           "train_seeds", "row_config", "evaluate_seeds", "markdown", "run"]

N_PAST = 10      # ABLATIONS (rows) and DEFAULT_STEPS live in train/ablations.py (no JAX: the CLI checks them first)
COLUMNS = ("L2P", "L2Q", "NPSS", "ADE", "FootSlide", "APD")


# ----------------------------------------------------------------------------- generic: N seeds, one program
def seed_keys(seeds) -> tuple:
    """Per-seed ``(init_keys, data_keys, train_keys)``, each a (N,) typed key array, as in run_training."""
    keys = jnp.stack([run_keys(int(s)) for s in seeds])                              # (N, 3)
    return keys[:, 0], keys[:, 1], keys[:, 2]


def stack_batches(batches: list) -> tuple:
    """N per-seed batches -> (stacked batch, vmap in_axes).

    Array leaves become (N, B, ...) with axis 0; 0-d leaves (e.g. the transition ``length``, a function of
    the step only) must agree across seeds and stay unbatched (axis None).
    """
    def leaf(*xs):
        if np.ndim(xs[0]) == 0:
            if any(np.asarray(x) != np.asarray(xs[0]) for x in xs):
                raise ValueError("0-d batch leaves differ across seeds; they cannot be shared")
            return xs[0]
        return np.stack(xs)

    stacked = jax.tree.map(leaf, *batches)
    axes = jax.tree.map(lambda x: None if np.ndim(x) == 0 else 0, batches[0])
    return stacked, axes


def make_vmapped(init_fn, train_step_fn, batch_axes) -> tuple:
    """Jitted ``vinit(keys (N,)) -> states`` and ``vstep(states, batch, train_keys (N,), i) -> (states, metrics)``.

    Leaves of ``states`` / ``metrics`` carry a leading seed axis N; seed n's step key is
    ``fold_in(train_keys[n], i)`` (the single-run step body of ``run_training``, vmapped).  ``states`` is
    donated.
    """
    from inbetween_jax.train.loop import step_body, strongly_typed
    vinit = jax.jit(lambda keys: jax.tree.map(strongly_typed, jax.vmap(init_fn)(keys)))
    vmapped = jax.vmap(step_body(train_step_fn), in_axes=(0, batch_axes, None, 0))
    vstep = jax.jit(lambda states, batch, keys, i: vmapped(states, batch, i, keys), donate_argnums=0)
    return vinit, vstep


def train_seeds(training, seeds, steps: int, mesh=None) -> tuple:
    """Train ``len(seeds)`` models of one config in one vmapped program.

    Args:
        training: :class:`~inbetween_jax.models.spec.Training` (``get_spec(name).make_training(cfg, data)``).
        mesh: optional 1-D mesh; states, keys and batches are split over it along the seed axis.
    Returns:
        ``(states, history, timing)``: states with a leading seed axis (N, ...); history: one dict of
        (N,) NumPy metrics per step; timing: {"compile_s", "train_s"} (first step counted as compile).
    """
    from inbetween_jax.train import shard_batch
    init_keys, data_keys, train_keys = seed_keys(seeds)
    place = (lambda t: t) if mesh is None else (lambda t: shard_batch(t, mesh))
    fold = jax.jit(jax.vmap(jax.random.fold_in, in_axes=(0, None)))

    def batch_at(i):
        keys = fold(data_keys, i)
        return stack_batches([training.batch_fn(i, keys[n]) for n in range(len(seeds))])

    vinit, vstep = make_vmapped(training.init_fn, training.step_fn, batch_at(0)[1])
    t0 = t1 = time.time()
    states, train_keys = place(vinit(place(init_keys))), place(train_keys)
    history, timing = [], {}
    for i in range(steps):
        batch = place(batch_at(i)[0])
        states, metrics = vstep(states, batch, train_keys, np.int32(i))
        history.append(metrics)
        if i == 0:
            jax.block_until_ready(metrics)
            timing["compile_s"], t1 = time.time() - t0, time.time()
    history = jax.device_get(history)
    timing["train_s"] = time.time() - t1 if steps else 0.0
    return states, history, timing


# ----------------------------------------------------------------------------- the ablation sweep (Table 6)
def _rows(model: str) -> dict:
    if model not in ABLATIONS:
        raise ValueError(f"no ablation rows for model {model!r} (choose {', '.join(ABLATIONS)})")
    return ABLATIONS[model]


def row_config(preset: str, row: str, frames: int, overrides=(), model: str = "scvae"):
    """Config of one row: the preset with ``row``'s switch off, trained for transitions up to ``frames``.

    ``tiny`` trains at a fixed transition length (data.trans_start = data.trans_max = frames); ``cpu`` /
    ``paper`` keep their progressive schedule with data.trans_max raised to at least ``frames``.
    """
    from inbetween_jax.models import get_spec
    from inbetween_jax.train import apply_overrides
    rows = _rows(model)
    if row not in rows:
        raise ValueError(f"unknown row {row!r}; choose from {', '.join(rows)}")
    cfg = get_spec(model).get_config(preset)
    switch = rows[row][1]
    if switch is not None:
        cfg = dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, **{switch: False}))
    d = cfg.data
    start, top = (frames, frames) if preset == "tiny" else (min(d.trans_start, frames), max(d.trans_max, frames))
    cfg = dataclasses.replace(cfg, data=dataclasses.replace(d, trans_start=start, trans_max=top))
    return apply_overrides(cfg, list(overrides))


def evaluate_seeds(cfg, states, seeds, test, x_mean, x_std, frames: int, samples: int,
                   model: str = "scvae") -> list:
    """Per-seed :func:`transition_metrics` dicts on ``test`` windows (sampling with each seed's key)."""
    from inbetween_jax.evaluation import transition_metrics
    from inbetween_jax.models import get_spec
    sample_transitions = get_spec(model).module("infer").sample_transitions
    out = []
    for n, seed in enumerate(seeds):
        state = jax.tree.map(lambda x: x[n], states)
        s = sample_transitions(cfg.model, state, test, N_PAST, frames, samples, seed=int(seed))
        out.append(transition_metrics(test, N_PAST, frames, s["q"], s["r"], x_mean, x_std))
    return out


def _mean_std(values) -> tuple:
    v = np.asarray(values, np.float64)
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0


def _cell(mean: float, std: float | None) -> str:
    from inbetween_jax.evaluation import format_value
    return format_value(mean) if std is None else f"{format_value(mean)} ± {format_value(std)}"


def markdown(rows: list, baseline: dict, title: str, note: str) -> str:
    """Rows ``{"row", "label", "per_seed": [metrics...], "loss": [...]}`` -> markdown, mean ± std cells."""
    from inbetween_jax.evaluation import markdown_table
    table = [{"row": "-", "config": "Slerp", **{c: _cell(baseline[c], None) for c in COLUMNS}, "final loss": "-"}]
    for r in rows:
        table.append({"row": r["row"], "config": r["label"], "final loss": _cell(*_mean_std(r["loss"])),
                      **{c: _cell(*_mean_std([m[c] for m in r["per_seed"]])) for c in COLUMNS}})
    return markdown_table(table, list(COLUMNS) + ["final loss"], title, keys=("row", "config")) + "\n\n" + note


def run(source, results_dir: str, preset: str = "tiny", rows=None, num_seeds: int = 3, steps=None,
        frames: int = 30, samples: int = 5, overrides=(), verbose: bool = True, model: str = "scvae") -> dict:
    """Train and evaluate every (row, seed); writes ``sweep_<model>.md`` / ``.json`` into ``results_dir``."""
    from inbetween_jax.baselines import interpolate_transition
    from inbetween_jax.data import l2p_stats, load_dataset, resolve_source
    from inbetween_jax.evaluation import transition_metrics
    from inbetween_jax.models import get_spec
    from inbetween_jax.train import config_to_dict, enable_compilation_cache, make_mesh

    t_start = time.time()
    enable_compilation_cache()
    spec, table_rows = get_spec(model), _rows(model)
    rows = list(rows or table_rows)
    for row in rows:
        _ = row_config(preset, row, frames, overrides, model)       # unknown rows / keys fail before any work
    steps = DEFAULT_STEPS[preset] if steps is None else int(steps)
    seeds = list(range(int(num_seeds)))
    source = resolve_source(source)
    test = load_dataset(source, "test")
    if N_PAST + frames >= test.window:
        raise ValueError(f"--frames {frames}: the {test.window}-frame test windows fit at most "
                         f"{test.window - N_PAST - 1} transition frames after {N_PAST} past frames")
    data = spec.load_data(row_config(preset, rows[0], frames, overrides, model), source, "train")
    x_mean, x_std = l2p_stats(load_dataset(source, "train").global_pose()[1])
    devices = math.gcd(len(seeds), jax.device_count())
    mesh = make_mesh(devices) if devices > 1 else None
    q, r = interpolate_transition(test.local_quats.astype(np.float64), test.root_pos.astype(np.float64), N_PAST,
                                  frames)
    baseline = transition_metrics(test, N_PAST, frames, q, r, x_mean, x_std)
    out_rows = []
    for row in rows:
        cfg = row_config(preset, row, frames, overrides, model)
        t0 = time.time()
        states, history, timing = train_seeds(spec.make_training(cfg, data), seeds, steps, mesh)
        per_seed = evaluate_seeds(cfg, states, seeds, test, x_mean, x_std, frames, samples, model)
        rec = {"row": row, "label": table_rows[row][0], "off": table_rows[row][1], "per_seed": per_seed,
               "loss": [float(x) for x in history[-1]["loss"]] if history else [float("nan")] * len(seeds),
               "wall_s": time.time() - t0, **timing, "config": config_to_dict(cfg)}
        out_rows.append(rec)
        if verbose:
            summary = ", ".join(f"{c} {_cell(*_mean_std([m[c] for m in per_seed]))}" for c in ("L2P", "L2Q", "NPSS"))
            print(f"{row:8s} {rec['wall_s']:6.1f} s (compile+step0 {timing.get('compile_s', 0):.1f} s): {summary}",
                  flush=True)
    wall = time.time() - t_start
    title = (f"{model} ablation sweep ({preset} preset, {steps} steps, {len(seeds)} seeds; {frames}-frame "
             f"transitions on {len(test)} test windows, {samples} samples)")
    note = (f"Source `{source}`. Mean ± std (ddof=1) over seeds {seeds}; each row's seeds trained as one vmapped "
            f"program{f' split over {devices} devices' if mesh is not None else ''}. L2P/L2Q/NPSS unitless, "
            f"ADE/APD in m, FootSlide in cm/frame; final loss = training loss at the last step (its terms differ "
            f"between rows). Wall {wall:.0f} s on {jax.device_count()} {jax.devices()[0].platform} device(s).")
    md = markdown(out_rows, baseline, title, note)
    result = {"model": model, "source": source, "preset": preset, "steps": steps, "seeds": seeds, "frames": frames,
              "samples": samples, "n_past": N_PAST, "windows": len(test), "devices": devices, "wall_s": wall,
              "baseline": {"Slerp": baseline}, "rows": out_rows, "markdown": md}
    os.makedirs(results_dir, exist_ok=True)
    with open(os.path.join(results_dir, f"sweep_{model}.json"), "w") as f:
        json.dump(result, f, indent=1)
    with open(os.path.join(results_dir, f"sweep_{model}.md"), "w") as f:
        f.write(md + "\n")
    return result
