"""S-CVAE ablation sweep (paper Table 6) with seed repeats: every config trains all its seeds in one program.

Rows: the full model and the full model with one ablation switch of ``ModelConfig`` turned off.  Within a
row the N seeds share one compiled step: the init is ``vmap``-ped over the seeds' PRNG keys and the pure
train step over (state, batch, key), so N seeds cost one compilation and one (batched) step per
iteration.  Rows change the parameter structure, so they run one after another.  With several devices the
seed axis is split over a mesh (``inbetween_jax.train.make_mesh``).

Seed ``s`` follows :func:`inbetween_jax.train.run_training` exactly: ``key(s)`` splits into init, data and
train keys, step ``i`` uses ``batch_fn(i, fold_in(data_key, i))`` and ``fold_in(train_key, i)``, so a
vmapped seed reproduces the single run of that seed (up to float rounding).

Evaluation: every (row, seed) samples ``--samples`` transitions of ``--frames`` frames between frame
``N_PAST - 1`` and frame ``N_PAST + frames`` of every test window and is scored with
:func:`inbetween_jax.evaluation.transition_metrics`; the table shows mean ± std (ddof=1) over seeds.

    python experiments/sweep_scvae.py [--source DIR] [--seeds 3] [--steps 200] [--preset tiny]
        [--rows full,no_bs,...] [--frames 30] [--samples 5] [--results results] [key=value ...]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

# row name -> (label of Table 6, ModelConfig switch turned off; None = full model)
ROWS = {"full": ("S-CVAE (full)", None), "no_bs": ("w/o BS", "bidirectional"),
        "no_li": ("w/o LI", "latent_interp"), "no_ba": ("w/o BA", "aligning"),
        "no_pm": ("w/o PM", "phase_moe"), "no_lstm": ("w/o LSTM", "encoder_lstm"),
        "no_d": ("w/o D", "discriminators"), "no_sl": ("w/o SL", "stitch_loss")}
N_PAST = 10
COLUMNS = ("L2P", "L2Q", "NPSS", "ADE", "FootSlide", "APD")
DEFAULT_STEPS = {"tiny": 200, "cpu": 2000, "paper": 20000}


def row_config(preset: str, row: str, frames: int, overrides=()):
    """Config of one row: the preset with ``row``'s switch off, trained for transitions up to ``frames``.

    ``tiny`` trains at a fixed transition length (trans_start = trans_max = frames); ``cpu`` / ``paper``
    keep their progressive schedule with trans_max raised to at least ``frames``.
    """
    from inbetween_jax.configs.scvae import get_config
    from inbetween_jax.train import apply_overrides
    if row not in ROWS:
        raise ValueError(f"unknown row {row!r}; choose from {', '.join(ROWS)}")
    cfg = get_config(preset)
    switch = ROWS[row][1]
    if switch is not None:
        cfg = dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, **{switch: False}))
    tr = cfg.train
    start, top = (frames, frames) if preset == "tiny" else (min(tr.trans_start, frames), max(tr.trans_max, frames))
    cfg = dataclasses.replace(cfg, train=dataclasses.replace(tr, trans_start=start, trans_max=top))
    return apply_overrides(cfg, list(overrides))


def seed_keys(seeds) -> tuple:
    """Per-seed ``(init_keys, data_keys, train_keys)``, each a (N,) typed key array, as in run_training."""
    keys = jnp.stack([jax.random.split(jax.random.key(int(s)), 3) for s in seeds])   # (N, 3)
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


def train_seeds(cfg, data, stats: dict, seeds, steps: int, mesh=None) -> tuple:
    """Train ``len(seeds)`` models of one config in one vmapped program.

    Args:
        data: :class:`inbetween_jax.models.scvae_train.TrainData`; stats: :func:`compute_stats` output.
        mesh: optional 1-D mesh; states, keys and batches are split over it along the seed axis.
    Returns:
        ``(states, history, timing)``: states with a leading seed axis (N, ...); history: one dict of
        (N,) NumPy metrics per step; timing: {"compile_s", "train_s"} (first step counted as compile).
    """
    from inbetween_jax.models import scvae_train as T
    from inbetween_jax.train import shard_batch
    init_fn = T.make_init_fn(cfg, stats, data.q.shape[2])
    step_fn = T.make_train_step(cfg, data.parents, cfg.train.trans_max + 1)
    batch_fn = T.batch_fn_factory(data, cfg.train)
    init_keys, data_keys, train_keys = seed_keys(seeds)
    place = (lambda t: t) if mesh is None else (lambda t: shard_batch(t, mesh))
    fold = jax.jit(jax.vmap(jax.random.fold_in, in_axes=(0, None)))

    def batch_at(i):
        keys = fold(data_keys, i)
        return stack_batches([batch_fn(i, keys[n]) for n in range(len(seeds))])

    vinit, vstep = make_vmapped(init_fn, step_fn, batch_at(0)[1])
    t0 = time.time()
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


def evaluate_seeds(cfg, states, seeds, test, x_mean, x_std, frames: int, samples: int) -> list:
    """Per-seed :func:`transition_metrics` dicts on ``test`` windows (sampling with each seed's key)."""
    from inbetween_jax.evaluation import transition_metrics
    from inbetween_jax.models.scvae_eval import sample_transitions
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
    fmt = (lambda x: f"{x:.4f}") if abs(mean) < 10 else (lambda x: f"{x:.2f}")
    return fmt(mean) if std is None else f"{fmt(mean)} ± {fmt(std)}"


def markdown(rows: list, baseline: dict, title: str, note: str) -> str:
    """Rows ``{"row", "label", "per_seed": [metrics...], "loss": [...]}`` -> markdown, mean ± std cells."""
    head = ["row", "config"] + list(COLUMNS) + ["final loss"]
    lines = [f"**{title}**", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines.append("| - | Slerp | " + " | ".join(_cell(baseline[c], None) for c in COLUMNS) + " | - |")
    for r in rows:
        cells = [_cell(*_mean_std([m[c] for m in r["per_seed"]])) for c in COLUMNS]
        lines.append(f"| {r['row']} | {r['label']} | " + " | ".join(cells) + f" | {_cell(*_mean_std(r['loss']))} |")
    return "\n".join(lines + ["", note])


def run(source, results_dir: str, preset: str = "tiny", rows=None, num_seeds: int = 3, steps=None,
        frames: int = 30, samples: int = 5, overrides=(), verbose: bool = True) -> dict:
    """Train and evaluate every (row, seed); writes ``sweep_scvae.md`` / ``.json`` into ``results_dir``."""
    from inbetween_jax.baselines import interpolate_transition
    from inbetween_jax.data import l2p_stats, load_dataset, resolve_source
    from inbetween_jax.evaluation import transition_metrics
    from inbetween_jax.models import scvae_train as T
    from inbetween_jax.train import config_to_dict, enable_compilation_cache, make_mesh

    t_start = time.time()
    enable_compilation_cache()
    rows = list(rows or ROWS)
    steps = DEFAULT_STEPS[preset] if steps is None else int(steps)
    seeds = list(range(int(num_seeds)))
    source = resolve_source(source)
    train, test = load_dataset(source, "train"), load_dataset(source, "test")
    if N_PAST + frames >= test.window:
        raise ValueError(f"--frames {frames}: the {test.window}-frame test windows fit at most "
                         f"{test.window - N_PAST - 1} transition frames after {N_PAST} past frames")
    data, stats = T.TrainData.from_windows(train), T.compute_stats(train)
    x_mean, x_std = l2p_stats(train.global_pose()[1])
    devices = math.gcd(len(seeds), jax.device_count())
    mesh = make_mesh(devices) if devices > 1 else None
    q, r = interpolate_transition(test.local_quats.astype(np.float64), test.root_pos.astype(np.float64), N_PAST,
                                  frames)
    baseline = transition_metrics(test, N_PAST, frames, q, r, x_mean, x_std)
    out_rows = []
    for row in rows:
        cfg = row_config(preset, row, frames, overrides)
        t0 = time.time()
        states, history, timing = train_seeds(cfg, data, stats, seeds, steps, mesh)
        per_seed = evaluate_seeds(cfg, states, seeds, test, x_mean, x_std, frames, samples)
        rec = {"row": row, "label": ROWS[row][0], "off": ROWS[row][1], "per_seed": per_seed,
               "loss": [float(x) for x in history[-1]["loss"]] if history else [float("nan")] * len(seeds),
               "wall_s": time.time() - t0, **timing, "config": config_to_dict(cfg)}
        out_rows.append(rec)
        if verbose:
            summary = ", ".join(f"{c} {_cell(*_mean_std([m[c] for m in per_seed]))}" for c in ("L2P", "L2Q", "NPSS"))
            print(f"{row:8s} {rec['wall_s']:6.1f} s (compile+step0 {timing.get('compile_s', 0):.1f} s): {summary}",
                  flush=True)
    wall = time.time() - t_start
    title = (f"S-CVAE ablation sweep ({preset} preset, {steps} steps, {len(seeds)} seeds; {frames}-frame "
             f"transitions on {len(test)} test windows, {samples} samples)")
    note = (f"Source `{source}`. Mean ± std (ddof=1) over seeds {seeds}; each row's seeds trained as one vmapped "
            f"program{f' split over {devices} devices' if mesh is not None else ''}. L2P/L2Q/NPSS unitless, "
            f"ADE/APD in m, FootSlide in cm/frame; final loss = training loss at the last step (its terms differ between rows). "
            f"Wall {wall:.0f} s on {jax.device_count()} {jax.devices()[0].platform} device(s).")
    md = markdown(out_rows, baseline, title, note)
    result = {"source": source, "preset": preset, "steps": steps, "seeds": seeds, "frames": frames,
              "samples": samples, "n_past": N_PAST, "windows": len(test), "devices": devices, "wall_s": wall,
              "baseline": {"Slerp": baseline}, "rows": out_rows, "markdown": md}
    os.makedirs(results_dir, exist_ok=True)
    with open(os.path.join(results_dir, "sweep_scvae.json"), "w") as f:
        json.dump(result, f, indent=1)
    with open(os.path.join(results_dir, "sweep_scvae.md"), "w") as f:
        f.write(md + "\n")
    return result


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="sweep_scvae", description=__doc__.split("\n")[0])
    ap.add_argument("--source", default=None, help="LaFAN1 / BVH folder or 'embedded' (default: $LAFAN1_DIR, "
                                                   "else the embedded CMU set)")
    ap.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1 per row")
    ap.add_argument("--steps", type=int, default=None, help="train steps (default: 200 tiny, 2000 cpu, 20000 paper)")
    ap.add_argument("--preset", default="tiny", choices=("tiny", "cpu", "paper"))
    ap.add_argument("--rows", default=",".join(ROWS), help=f"comma list of {', '.join(ROWS)}")
    ap.add_argument("--frames", type=int, default=30, help="transition length trained and evaluated")
    ap.add_argument("--samples", type=int, default=5, help="sampled transitions per test window")
    ap.add_argument("--results", default="results")
    ap.add_argument("overrides", nargs="*", help="config overrides key=value (every row)")
    args = ap.parse_args(argv)
    rows = [r.strip() for r in args.rows.split(",") if r.strip()]
    out = run(args.source, args.results, args.preset, rows, args.seeds, args.steps, args.frames, args.samples,
              args.overrides)
    print(out["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
