"""One run-folder format for every model: ``write_run`` / ``load_run`` / ``restore_state``.

A run folder holds::

    run.json          model name, preset + overrides, full config, skeleton, frame rate, normalisation
                      statistics, data provenance, training history (steps, wall time)
    checkpoints/<step>/   orbax state written by :func:`inbetween_jax.train.run_training`
    metrics.csv, metrics.jsonl

A *shipped* run folder (:mod:`inbetween_jax.shipped`) holds ``run.json`` (with a ``shipped`` record: step, dtype,
kept key paths, provenance) and ``params.npz`` (the inference parameters, '/'-joined key paths) instead of
``checkpoints/``; :func:`load_run` and :func:`restore_state` read it the same way.

``run.json`` is written (atomically) before training starts; resuming with another model, preset or core config
(anything but ``train.num_steps`` / ``log_every`` / ``ckpt_every`` / ``ema_eval``) is refused with a one-line
:class:`RunError`.
Statistics are JSON lists; :func:`load_run` returns them as float32 NumPy arrays.
"""
from __future__ import annotations

import dataclasses
import datetime
import json
import os
from typing import Any

import numpy as np

from inbetween_jax.errors import NPZ_READ_ERRORS

__all__ = ["RUN_FILE", "WEIGHTS_FILE", "SELECTION_FILE", "FORMAT", "RunError", "Run", "write_run", "load_run",
           "load_run_file", "record_training", "restore_state", "selected_step", "to_json_arrays", "from_json_arrays",
           "flat_leaves"]

RUN_FILE = "run.json"
WEIGHTS_FILE = "params.npz"
SELECTION_FILE = "selection.json"     # the checkpoint chosen on the validation split (train/select.py)
FORMAT = 1
_NOT_CORE = ("num_steps", "log_every", "ckpt_every", "ema_eval")


class RunError(ValueError):
    """A run folder that cannot be used; ``str(err)`` is one line naming the folder and the problem."""


@dataclasses.dataclass
class Run:
    """A run folder's metadata (``run.json``) and its latest (or chosen) checkpoint step."""
    run_dir: str
    model: str
    preset: str
    overrides: list
    config: dict                     # config_to_dict of the training config
    skeleton: dict | None            # Skeleton.to_dict() of the training data
    fps: float | None
    stats: dict                      # name -> float32 array (normalisation statistics)
    data: dict                       # provenance: source, files, counts, split
    extra: dict                      # model-specific metadata
    history: list
    step: int | None                 # checkpoint step to restore (None: no checkpoint yet)
    weights: str | None = None       # params.npz of a shipped run (restored instead of checkpoints/)
    shipped: dict | None = None      # run.json's "shipped" record (step, dtype, keep, provenance)

    @property
    def checkpoint_dir(self) -> str:
        return os.path.join(self.run_dir, "checkpoints")


def to_json_arrays(tree: Any) -> Any:
    """Arrays (NumPy / JAX) inside dicts / lists -> nested lists of Python floats / ints."""
    if isinstance(tree, dict):
        return {str(k): to_json_arrays(v) for k, v in tree.items()}
    if isinstance(tree, (list, tuple)):
        return [to_json_arrays(v) for v in tree]
    if hasattr(tree, "shape") and hasattr(tree, "dtype"):
        return np.asarray(tree).tolist()
    return tree


def from_json_arrays(tree: Any) -> Any:
    """Inverse of :func:`to_json_arrays` for a dict of statistics: lists -> float32 arrays."""
    if isinstance(tree, dict):
        return {k: from_json_arrays(v) for k, v in tree.items()}
    if isinstance(tree, list):
        return np.asarray(tree, np.float32)
    return tree


def _core(config: dict) -> dict:
    c = json.loads(json.dumps(config or {}))
    for k in _NOT_CORE:
        c.get("train", {}).pop(k, None)
    return c


def _added_keys(old: dict, new: dict) -> dict:
    """``old`` with the keys only ``new`` has (config fields added since the run was written) taken from
    ``new``, so a run resumes under a newer version whose added switches keep their defaults."""
    out = dict(old)
    for k, v in new.items():
        if k not in out:
            out[k] = v
        elif isinstance(v, dict) and isinstance(out[k], dict):
            out[k] = _added_keys(out[k], v)
    return out


def _read(path: str, run_dir: str) -> dict:
    try:
        with open(path) as f:
            meta = json.load(f)
    except FileNotFoundError:
        raise RunError(f"{run_dir}: not a run folder (no {RUN_FILE})") from None
    except (OSError, ValueError) as e:
        raise RunError(f"{run_dir}: {RUN_FILE} is unreadable ({type(e).__name__}: "
                       f"{str(e).splitlines()[0] if str(e) else 'empty'})") from None
    if not isinstance(meta, dict) or "model" not in meta or "config" not in meta:
        raise RunError(f"{run_dir}: {RUN_FILE} is not a run description (no model / config)")
    if meta.get("format", 0) > FORMAT:
        raise RunError(f"{run_dir}: {RUN_FILE} has format {meta['format']}, newer than this version ({FORMAT})")
    return meta


def _atomic_json(path: str, obj: dict) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(obj, f, indent=1)
    os.replace(tmp, path)


def write_run(run_dir: str, *, model: str, preset: str, overrides, config: dict, skeleton: dict | None = None,
              fps: float | None = None, stats: dict | None = None, data: dict | None = None,
              extra: dict | None = None) -> dict:
    """Create ``run_dir/run.json`` (or check that an existing one describes the same training); returns it.

    Raises:
        RunError: the folder holds a run of another model / preset / core config.
    """
    os.makedirs(run_dir, exist_ok=True)
    path = os.path.join(run_dir, RUN_FILE)
    meta = {"format": FORMAT, "model": model, "preset": preset, "overrides": list(overrides), "config": config,
            "skeleton": skeleton, "fps": None if fps is None else float(fps), "stats": to_json_arrays(stats or {}),
            "data": to_json_arrays(data or {}), "extra": to_json_arrays(extra or {}), "history": []}
    if os.path.exists(path):
        old = _read(path, run_dir)
        if old["model"] != model or _core(_added_keys(old["config"], config)) != _core(config):
            raise RunError(f"{run_dir} holds a {old['model']} run with another config (preset {old.get('preset')}, "
                           f"overrides {old.get('overrides')}); pass the same settings to resume or choose another "
                           "--run-dir")
        meta["history"] = old.get("history", [])
        meta["created"] = old.get("created")
    meta.setdefault("created", None)
    meta["created"] = meta["created"] or datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    _atomic_json(path, meta)
    return meta


def record_training(run_dir: str, steps: int, wall_s: float, **info) -> None:
    """Append ``{"steps", "wall_s", "finished", **info}`` to ``run.json``'s training history."""
    path = os.path.join(run_dir, RUN_FILE)
    meta = _read(path, run_dir)
    meta.setdefault("history", []).append({
        "steps": int(steps), "wall_s": round(float(wall_s), 1),
        "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), **info})
    _atomic_json(path, meta)


def load_run_file(run_dir: str, name: str, loader, need: str):
    """``loader(path)`` of the file ``name`` in ``run_dir`` (e.g. a motion bank), which ``need`` (the switch that
    uses it) requires.  Raises RunError (one line) when it is missing, or when ``loader`` raises UserError."""
    from inbetween_jax.errors import UserError
    path = os.path.join(run_dir, name)
    if not os.path.isfile(path):
        raise RunError(f"{run_dir}: {need} needs {name}, which is missing (write it with inbetween build-bank)")
    try:
        return loader(path)
    except UserError as e:
        raise RunError(str(e)) from None


def _checkpoint_steps(ckpt_dir: str) -> list[int]:
    """Finished checkpoint steps (``<step>/`` folders that hold files), without starting orbax."""
    if not os.path.isdir(ckpt_dir):
        return []
    steps = []
    for name in os.listdir(ckpt_dir):
        full = os.path.join(ckpt_dir, name)
        if name.isdigit() and os.path.isdir(full) and os.listdir(full):
            steps.append(int(name))
    return sorted(steps)


def selected_step(run_dir: str) -> int | None:
    """The step recorded in ``selection.json`` (written by :mod:`inbetween_jax.train.select`; None when the run
    has no selection)."""
    path = os.path.join(run_dir, SELECTION_FILE)
    if not os.path.exists(path):
        return None
    try:
        with open(path) as f:
            return int(json.load(f)["step"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def load_run(run_dir: str, step: int | None = None, need_checkpoint: bool = True) -> Run:
    """Read a run folder; ``step`` defaults to the step chosen on the validation split (``selection.json``,
    :mod:`inbetween_jax.train.select`), else the latest checkpoint.

    Raises:
        RunError: one line naming the folder: missing, not a run folder, unreadable ``run.json``, no checkpoint
            (when ``need_checkpoint``), or the asked ``step`` is not there.
    """
    if not os.path.exists(run_dir):
        raise RunError(f"run folder {run_dir!r} does not exist")
    if not os.path.isdir(run_dir):
        raise RunError(f"{run_dir}: not a folder (expected a training run folder)")
    meta = _read(os.path.join(run_dir, RUN_FILE), run_dir)
    if isinstance(meta.get("shipped"), dict):
        return _shipped_run(run_dir, meta, step)
    steps = _checkpoint_steps(os.path.join(run_dir, "checkpoints"))
    if step is None:
        chosen = selected_step(run_dir)
        step = chosen if chosen in steps else (steps[-1] if steps else None)
    elif step not in steps:
        raise RunError(f"{run_dir}: no checkpoint at step {step} (found {steps or 'none'})")
    if step is None and need_checkpoint:
        raise RunError(f"{run_dir}: no checkpoint found (expected checkpoints/<step>/ written by training)")
    return _run(run_dir, meta, step)


def _run(run_dir: str, meta: dict, step, **kw) -> Run:
    return Run(run_dir=os.path.abspath(run_dir), model=meta["model"], preset=meta.get("preset", ""),
               overrides=list(meta.get("overrides", [])), config=meta["config"], skeleton=meta.get("skeleton"),
               fps=meta.get("fps"), stats=from_json_arrays(meta.get("stats", {})), data=meta.get("data", {}),
               extra=meta.get("extra", {}), history=meta.get("history", []), step=step, **kw)


def _shipped_run(run_dir: str, meta: dict, step: int | None) -> Run:
    shipped = meta["shipped"]
    path = os.path.join(run_dir, WEIGHTS_FILE)
    if not os.path.isfile(path):
        raise RunError(f"{run_dir}: shipped weights without {WEIGHTS_FILE}")
    if not isinstance(shipped.get("step"), int):
        raise RunError(f"{run_dir}: {RUN_FILE} records no shipped step")
    if step is not None and step != shipped["step"]:
        raise RunError(f"{run_dir}: shipped weights hold step {shipped['step']} only (asked for step {step})")
    return _run(run_dir, meta, shipped["step"], weights=os.path.abspath(path), shipped=shipped)


def restore_state(run: Run, target: Any) -> Any:
    """Restore ``run.step``'s state into the structure of ``target`` (arrays or ``jax.ShapeDtypeStruct``)."""
    from .checkpoint import Checkpointer
    if run.weights:
        return _restore_weights(run, target)
    if run.step is None:
        raise RunError(f"{run.run_dir}: no checkpoint to restore")
    ckpt = Checkpointer(run.checkpoint_dir)
    try:
        return ckpt.restore(run.step, target)
    except (ValueError, KeyError, OSError, TypeError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise RunError(f"{run.checkpoint_dir}/{run.step}: cannot restore the checkpoint ({msg[:200]})") from None
    finally:
        ckpt.close()


def _key_name(k) -> str:
    for attr in ("key", "idx", "name"):          # DictKey, SequenceKey, GetAttrKey
        if hasattr(k, attr):
            return str(getattr(k, attr))
    return str(k)


def flat_leaves(tree: Any) -> dict:
    """``{"a/b/0/c": leaf}``: the leaves of a pytree under their '/'-joined key paths (tree order)."""
    import jax
    leaves, _ = jax.tree_util.tree_flatten_with_path(tree)
    return {"/".join(_key_name(k) for k in path): leaf for path, leaf in leaves}


def _under(path: str, prefixes) -> bool:
    return any(path == p or path.startswith(p + "/") for p in prefixes)


def _restore_weights(run: Run, target: Any) -> Any:
    """A shipped run's ``params.npz`` in the structure of ``target``: arrays cast to the target's dtypes; leaves
    outside the kept key paths (optimizer state, discriminators ...) are zeros of the target's shape / dtype."""
    import jax
    import jax.numpy as jnp
    keep = list(run.shipped.get("keep", []))
    try:
        with np.load(run.weights, allow_pickle=False) as z:
            stored = {k: z[k] for k in z.files}
    except (*NPZ_READ_ERRORS, KeyError) as e:
        msg = str(e).splitlines()[0] if str(e) else "empty"
        raise RunError(f"{run.weights}: cannot read the shipped weights ({type(e).__name__}: {msg[:200]})") from None
    leaves, treedef = jax.tree_util.tree_flatten_with_path(target)
    out = []
    for path, leaf in leaves:
        name = "/".join(_key_name(k) for k in path)
        shape, dtype = tuple(leaf.shape), leaf.dtype
        if name in stored:
            arr = stored[name]
            if tuple(arr.shape) != shape:
                raise RunError(f"{run.weights}: {name} has shape {tuple(arr.shape)}, the model expects {shape} "
                               "(weights of another config)")
            out.append(jnp.asarray(arr, dtype))
        elif _under(name, keep):
            raise RunError(f"{run.weights}: {name} is missing (weights of another config or version)")
        else:
            out.append(jnp.zeros(shape, dtype))
    return jax.tree_util.tree_unflatten(treedef, out)
