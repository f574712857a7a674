"""Generic, model-agnostic training driver with bitwise-reproducible resume.

Every model provides three pure pieces and the driver does the rest (jit, PRNG, checkpoints, logs)::

    init_fn(key) -> state                        # pytree of arrays / PRNG keys (params, opt_state, ...)
    train_step_fn(state, batch, key) -> (state, metrics)   # pure; metrics: dict of scalar arrays
    batch_fn(step, key) -> batch                 # deterministic in (step, key)

Flax NNX models: ``graphdef, params = nnx.split(model)`` and close over ``graphdef`` in the step
function; the state pytree must only hold arrays (``nnx.State`` / optax states are fine).

Randomness.  ``base = jax.random.key(seed)`` is split once into ``init_key, data_base, train_base``.
Step ``i`` (0-based: the state has ``i`` updates applied) uses
``batch_fn(i, jax.random.fold_in(data_base, i))`` and ``train_step_fn(state, batch, fold_in(train_base, i))``.
No key is carried across the Python loop, so a resumed run sees exactly the batches and keys of an
uninterrupted run, and (on the same machine / XLA build) reproduces it bitwise.

Step numbering in logs and checkpoints: ``step = n`` means ``n`` updates have been applied; a
checkpoint at step 10 resumes with ``i = 10`` and logs steps 11, 12, ...

Several processes (``train.distributed``): the same call runs in every process.  Without a ``mesh`` the
driver uses the global data mesh; every process computes the same global batch and keeps its rows,
the state is replicated, orbax writes each checkpoint once, and only process 0 writes the metric files
and shows progress (all processes return the same ``logged`` rows).
"""

from __future__ import annotations

import math
import os
import time
import warnings
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np

from .checkpoint import Checkpointer
from .config import config_to_dict
from . import distributed
from .logging import MetricLogger, ProgressBar
from .parallel import make_mesh, make_parallel_step_fn, replicate
from .step import step_body, strongly_typed

__all__ = ["enable_compilation_cache", "default_cache_dir", "make_step_fn", "run_keys", "run_training", "step_body",
           "strongly_typed"]

def default_cache_dir() -> str:
    """``$INBETWEEN_JAX_CACHE/jax_cache`` (default root ``~/.cache/inbetween_jax``, :func:`inbetween_jax.paths.cache_root`),
    absolute: the package-wide cache root holds the window caches, compiled executables their own sub-folder."""
    from inbetween_jax.paths import cache_root
    return os.path.join(cache_root(), "jax_cache")


def enable_compilation_cache(cache_dir: str | None = None, min_compile_time_secs: float = 0.1) -> str:
    """Turn on JAX's persistent compilation cache (works on CPU and GPU); returns the cache folder.

    Only the JAX config is changed (the one piece of global state this package touches).  Call it
    before the first compilation: JAX fixes the cache location when it first uses the cache.
    """
    path = os.path.abspath(os.path.expanduser(cache_dir)) if cache_dir else default_cache_dir()
    os.makedirs(path, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_time_secs))
    return path


class BoundStep:
    """A jitted ``(state, batch, i, base)`` step bound to one base key: call as ``step(state, batch, i)``.

    ``lower`` / ``trace`` take the same three arguments (for compile-time measurements).
    """

    def __init__(self, jitted: Callable, base: jax.Array):
        self.jitted, self.base = jitted, base

    def __call__(self, state, batch, i):
        return self.jitted(state, batch, i, self.base)

    def lower(self, state, batch, i):
        return self.jitted.lower(state, batch, i, self.base)

    def trace(self, state, batch, i):
        return self.jitted.trace(state, batch, i, self.base)


def make_step_fn(train_step_fn: Callable, train_base: jax.Array) -> BoundStep:
    """:func:`step_body` jitted with the state argument donated, bound to ``train_base``."""
    return BoundStep(jax.jit(step_body(train_step_fn), donate_argnums=0), train_base)


def _row(step: int, metrics: dict) -> dict:
    """The row :meth:`MetricLogger.log` would return, without writing it (non-primary processes)."""
    return {"step": int(step), **{k: np.asarray(v).item() for k, v in metrics.items() if k != "step"}}


def _join_processes() -> None:
    """Join the multi-process runtime when a launcher asked for it but the program did not."""
    if distributed.requested_processes() > 1 and not jax.distributed.is_initialized():
        try:
            distributed.initialize()
        except RuntimeError as e:
            raise RuntimeError(f"{distributed.ENV_NUM_PROCESSES}={distributed.requested_processes()} is set but "
                               "JAX was used before joining the other processes: call "
                               "inbetween_jax.train.distributed.initialize() at the start of the program") from e


def _check_finite(step: int, metrics: dict) -> None:
    for name, value in metrics.items():
        v = np.asarray(value)
        if np.issubdtype(v.dtype, np.floating) and not np.all(np.isfinite(v)):
            raise FloatingPointError(f"non-finite loss '{name}' at step {step}")


def run_keys(seed: int) -> jax.Array:
    """(3,) keys ``init_key, data_base, train_base`` of a run with ``seed`` (see the module docstring)."""
    return jax.random.split(jax.random.key(seed), 3)


def run_training(init_fn: Callable[[jax.Array], Any],
                 train_step_fn: Callable[[Any, Any, jax.Array], tuple[Any, dict]],
                 batch_fn: Callable[[int, jax.Array], Any],
                 config: Any, run_dir: str | os.PathLike, num_steps: int, log_every: int = 100,
                 ckpt_every: int = 1000, seed: int = 0, *, max_to_keep: int = 3, progress: bool = True,
                 compilation_cache: bool = True, mesh: Any = None) -> tuple[Any, list[dict]]:
    """Train for ``num_steps`` total updates, resuming from ``run_dir/checkpoints`` when possible.

    Args:
        init_fn: ``key -> state`` (pytree of arrays / typed PRNG keys).
        train_step_fn: pure ``(state, batch, key) -> (state, metrics)``; ``metrics`` maps names to
            scalar arrays.  Jitted once by the driver with the state donated.
        batch_fn: ``(step: int, key) -> batch`` (pytree of arrays), deterministic in its arguments.
        config: dataclass / dict, stored as JSON in every checkpoint.
        run_dir: run folder: ``checkpoints/``, ``metrics.csv``, ``metrics.jsonl``.
        num_steps: total number of updates (including those done before a resume).
        log_every: log (and check finiteness of) metrics every this many steps, and at the last step.
        ckpt_every: checkpoint every this many steps, and at the last step.
        seed: base PRNG seed (see module docstring for how keys are derived).
        max_to_keep: checkpoints kept on disk.  progress: show a tqdm bar.
        compilation_cache: call :func:`enable_compilation_cache` first.
        mesh: optional 1-D ``jax.sharding.Mesh`` (:func:`inbetween_jax.train.make_mesh`): data-parallel
            training, state replicated and every batch split over the mesh (see ``train.parallel``).
            Under several processes it defaults to the global mesh over all processes' devices.
    Returns:
        ``(state, logged)``: the final state and the rows logged *by this call*,
        each ``{"step": n, name: float, ...}``.
    Raises:
        FloatingPointError: ``"non-finite loss 'name' at step N"`` for the first NaN/inf metric; all
            metrics are checked (in step order) before any checkpoint, so no bad state is saved.
    """
    _join_processes()
    if compilation_cache:
        enable_compilation_cache()
    if mesh is None and jax.process_count() > 1:
        mesh = make_mesh()
    primary = jax.process_index() == 0
    run_dir = os.path.abspath(os.fspath(run_dir))
    log_every, ckpt_every = max(1, int(log_every)), max(1, int(ckpt_every))
    init_key, data_base, train_base = run_keys(seed)

    ckpt = Checkpointer(os.path.join(run_dir, "checkpoints"), max_to_keep=max_to_keep, save_every=ckpt_every)
    logger = bar = None
    try:
        start = ckpt.latest_step()
        wall0 = 0.0                           # training seconds before this call (resumed runs)
        if start is None:
            start = 0
            state = jax.tree.map(strongly_typed, init_fn(init_key))
        else:
            extra = ckpt.restore_extra(start)
            wall0 = float(extra.get("train_wall_s", 0.0))
            if extra.get("seed", seed) != seed:
                warnings.warn(f"resuming {run_dir} (seed {extra.get('seed')}) with seed {seed}: "
                              "the run will not reproduce an uninterrupted one", stacklevel=2)
            state = ckpt.restore(start, jax.eval_shape(init_fn, init_key))
            state = jax.tree.map(strongly_typed, state)

        logger = MetricLogger(run_dir, resume_step=start) if primary else None
        bar = ProgressBar(num_steps, initial=start, disable=not (progress and primary))
        if mesh is None:
            step_fn = make_step_fn(train_step_fn, train_base)
        else:
            state, step_fn = replicate(state, mesh), make_parallel_step_fn(train_step_fn, train_base, mesh)
        config_json = config_to_dict(config)
        logged: list[dict] = []
        pending: list[tuple[int, dict]] = []  # device metrics not yet checked (avoids a sync per step)

        t_start = time.perf_counter()
        for i in range(start, num_steps):
            batch = batch_fn(i, jax.random.fold_in(data_base, i))
            state, metrics = step_fn(state, batch, np.int32(i))
            n = i + 1
            pending.append((n, metrics))
            is_last = n == num_steps
            do_log, do_ckpt = n % log_every == 0 or is_last, n % ckpt_every == 0 or is_last
            if do_log or do_ckpt:
                host = jax.device_get(pending)
                pending = []
                for s, m in host:
                    _check_finite(s, m)
                if do_log:
                    logged.append(logger.log(n, host[-1][1]) if logger is not None else _row(n, host[-1][1]))
                bar.update(len(host), metrics=host[-1][1] if do_log else None)
            if do_ckpt:
                ckpt.save(n, state, extra_json={"step": n, "seed": seed, "data": {"next_step": n},
                                                "config": config_json,
                                                "train_wall_s": round(wall0 + time.perf_counter() - t_start, 2)},
                          force=True)
        return state, logged
    finally:
        if bar is not None:
            bar.close()
        if logger is not None:
            logger.close()
        ckpt.close()
