"""Train a registered model into a run folder: the one code path behind ``inbetween train`` and ``make train``.

    run_dir, logged = train_model("cae", preset="tiny", overrides=["train.num_steps=20"], source="embedded")

Loads the model's training data (``source``: a LaFAN1 / BVH folder, ``"embedded"``, or None for ``$LAFAN1_DIR``
else the embedded CMU set), builds its :class:`~inbetween_jax.models.spec.Training`, writes ``run.json``
(:mod:`inbetween_jax.train.run`) and runs :func:`inbetween_jax.train.run_training` (resumes from the folder's
latest checkpoint; same seed, same result).
"""
from __future__ import annotations

import os
import time
from typing import Callable, Sequence

from inbetween_jax.models import get_spec

__all__ = ["default_run_dir", "build_config", "train_model", "save_initial_state"]


def default_run_dir(model: str) -> str:
    """``runs/<model>`` (relative to the working folder)."""
    return os.path.join("runs", model)


def build_config(model: str, preset: str | None = None, overrides: Sequence[str] = ()):
    """The preset's config with ``key=value`` overrides applied (ConfigError on a bad key or value)."""
    from inbetween_jax.train.config import apply_overrides
    spec = get_spec(model)
    preset = preset or spec.default_preset
    if preset not in spec.presets:
        raise ValueError(f"unknown preset {preset!r} for {model} (choose {', '.join(spec.presets)})")
    return apply_overrides(spec.get_config(preset), list(overrides))


def train_model(model: str, preset: str | None = None, overrides: Sequence[str] = (), source: str | None = None,
                run_dir: str | None = None, progress: bool = True, log: Callable[[str], None] | None = print,
                mesh=None, stop_at: int | None = None):
    """Train (or resume) ``model``; returns ``(run_dir, logged rows)``.  ``stop_at``: stop after this step with the
    schedule of the full run unchanged (a later call without it resumes to the end).

    Raises:
        ValueError (ConfigError, BVHError, RunError) / OSError: one-line problems with the inputs;
        FloatingPointError: a non-finite loss (names the step).
    """
    from inbetween_jax.data import resolve_source
    from inbetween_jax.train import config_to_dict, run_training
    from inbetween_jax.train.run import _checkpoint_steps, record_training, write_run
    spec = get_spec(model)
    preset = preset or spec.default_preset
    cfg = build_config(model, preset, overrides)
    run_dir = run_dir or default_run_dir(model)
    src = resolve_source(source)
    data = spec.load_data(cfg, src, cfg.train.split)
    training = spec.make_training(cfg, data)
    meta = dict(training.meta)
    meta["data"] = {"source": src, **meta.get("data", {})}
    import jax
    primary = jax.process_index() == 0      # run-level files once: several processes would race on them
    if primary:
        write_run(run_dir, model=model, preset=preset, overrides=list(overrides), config=config_to_dict(cfg),
                  **meta)
        for name, write in training.files.items():     # e.g. the S-CVAE's transition bank (model.bank_base)
            write(os.path.join(run_dir, name))
    if log:
        log(f"{model} ({preset}): {training.describe or 'training'}; {training.num_steps} steps -> {run_dir}")
    tc = cfg.train
    if training.num_steps == 0:
        save_initial_state(run_dir, training.init_fn, tc.seed)
        return run_dir, []
    end_step = training.num_steps if stop_at is None else max(1, min(int(stop_at), training.num_steps))
    done = max(_checkpoint_steps(os.path.join(run_dir, "checkpoints")), default=0)
    complete = done >= end_step                      # a finished run run again: say so instead of a full bar
    if complete and log:
        log(f"{model}: training already complete (step {done} of {end_step}) in {run_dir}")
    t0 = time.time()
    _, logged = run_training(training.init_fn, training.step_fn, training.batch_fn, cfg, run_dir,
                             end_step, tc.log_every, tc.ckpt_every, tc.seed,
                             progress=progress and not complete, mesh=mesh, max_to_keep=tc.keep_checkpoints or None)
    wall = time.time() - t0
    if not primary:
        return run_dir, logged
    if not complete:
        record_training(run_dir, end_step, wall)
    bench = spec.module("bench")
    from inbetween_jax.data.datasets import is_fit_split
    if is_fit_split(tc.split) and hasattr(bench, "val_score"):
        from inbetween_jax.train.select import select_with_bench
        try:
            select_with_bench(run_dir, src, bench, log=log)
        except ValueError as e:     # e.g. validation motion too short for the score's windows
            if log:
                log(f"checkpoint selection skipped: {e}; the run opens at its latest checkpoint (select later: "
                    f"inbetween select-checkpoint {run_dir})")
    if log and logged:
        last = {k: round(v, 5) if isinstance(v, float) else v for k, v in logged[-1].items()}
        log(f"done in {wall:.0f} s; last logged: {last}")
    return run_dir, logged


def save_initial_state(run_dir: str, init_fn: Callable, seed: int) -> None:
    """Checkpoint 0 of a run: the state ``run_training`` would start from (``train.num_steps=0``), without
    compiling a training step (used for untrained runs in tests and for inspecting an initialisation)."""
    from inbetween_jax.train.checkpoint import Checkpointer
    from inbetween_jax.train.loop import run_keys
    init_key = run_keys(seed)[0]                                 # the key run_training initialises with
    with Checkpointer(os.path.join(os.path.abspath(run_dir), "checkpoints")) as ckpt:
        if ckpt.latest_step() is None:
            ckpt.save(0, init_fn(init_key), extra_json={"step": 0, "seed": seed}, force=True)
