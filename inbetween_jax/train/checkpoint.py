"""Thin wrapper over ``orbax.checkpoint.CheckpointManager`` for training state.

Each checkpoint ``<directory>/<step>/`` holds two orbax items:

* ``state``: the JAX pytree (params, opt_state, step counters, PRNG keys, ...), saved with
  ``ocp.args.StandardSave`` and restored with ``ocp.args.StandardRestore`` into the structure, shapes,
  dtypes and shardings of a target pytree;
* ``extra``: a JSON dict (data-iterator position, config, seed, ...), ``ocp.args.JsonSave``.

PRNG keys: typed key arrays (``jax.random.key``) cannot be serialised directly, so every leaf whose
dtype is a PRNG key is stored as ``jax.random.key_data(key)`` (uint32, shape ``key.shape + (2,)`` for
threefry) and rebuilt on restore with ``jax.random.wrap_key_data(data, impl=<impl of the target>)``.
Raw uint32 keys (``jax.random.PRNGKey``) are ordinary arrays and round-trip as such.

Orbax notes (0.12.x): the directory must be absolute (relative paths are resolved here); saves are
asynchronous, so ``wait()`` before reading files; the data is copied to host memory *before*
``save`` returns, so the caller may donate / overwrite the device buffers right away (on CPU
``np.asarray`` aliases the device buffer, hence the explicit copy); a step that already exists raises
``StepAlreadyExistsError`` (we skip it instead); unfinished ``*.orbax-checkpoint-tmp`` folders left by a
killed process are ignored by ``latest_step`` and removed on the next construction.

Several processes (``jax.distributed``): every process constructs the ``Checkpointer`` and calls
``save`` / ``restore`` with the same arguments; orbax synchronises them with barriers and only the
primary process (``jax.process_index() == 0``) writes the files (numpy leaves, JSON items, metadata).
The folder must be shared by all processes (one file system).  Restored arrays land on this process's
first local device; the driver then replicates them over the global mesh.

Damaged checkpoints (an empty step folder, zero-byte files, a missing or unreadable metadata file, a
folder without checkpoints, array data orbax cannot read) raise :class:`CheckpointError`, one line naming the
folder and the problem; orbax's own absl log lines are silenced during these calls, and the late tracebacks of
reads still in flight when a restore failed are dropped (:func:`_drop_late_read_errors`).
"""

from __future__ import annotations

import contextlib
import gc
import json
import logging
import os
import shutil
import sys
import traceback
from typing import Any, Iterator

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp

__all__ = ["Checkpointer", "CheckpointError", "check_step_dir"]

# files orbax writes into every finished step folder, and into each item folder
_STEP_METADATA = "_CHECKPOINT_METADATA"
_ITEM_METADATA = {"state": "_METADATA", "extra": "metadata"}


class CheckpointError(ValueError):
    """A checkpoint folder that cannot be read; ``str(err)`` is one line naming the folder and the problem."""


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Silence orbax's absl log lines (and asyncio's "exception never retrieved") for the duration.

    Only these two loggers' levels change, and they are restored on exit; the late reports of a failed read are
    dropped for good (:func:`_drop_late_read_errors`).
    """
    loggers = [logging.getLogger(name) for name in ("absl", "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    _drop_late_read_errors()
    try:
        yield
    except BaseException:
        gc.collect()  # failed tensorstore futures log when collected: do it while silenced
        raise
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def _is_closed_loop_report(unraisable) -> bool:
    """An unraisable ``RuntimeError('Event loop is closed')``: what tensorstore reads still in flight report when
    they finish after orbax's event loop closed on a failed restore."""
    exc = unraisable.exc_value
    return isinstance(exc, RuntimeError) and str(exc) == "Event loop is closed"


_NEVER_RETRIEVED = ("Task exception was never retrieved", "Future exception was never retrieved")   # asyncio's


class _LateFutureFilter(logging.Filter):
    """Drops asyncio's "Task / Future exception was never retrieved" records of orbax's or tensorstore's reads
    (the same late reads' errors); every other record passes."""

    def filter(self, record: logging.LogRecord) -> bool:
        if not str(record.msg).startswith(_NEVER_RETRIEVED) or not record.exc_info:
            return True
        exc = record.exc_info[1]
        where = str(exc) + "".join(traceback.format_tb(exc.__traceback__)) if exc is not None else ""
        return "orbax" not in where and "tensorstore" not in where


def _drop_late_read_errors() -> None:
    """When an orbax read fails, the reads still in flight finish on tensorstore's threads after orbax closed its
    event loop -- during orbax's own teardown or after the one-line error was raised -- and each reports a
    traceback (an unraisable "Event loop is closed", asyncio's "exception was never retrieved").  Called before
    every orbax call: from then on those two reports, and only those, are dropped (the current
    ``sys.unraisablehook`` is wrapped unless it already is; asyncio's logger gets a filter once)."""
    current = sys.unraisablehook
    if not getattr(current, "drops_closed_loop_reports", False):
        def hook(unraisable):
            if not _is_closed_loop_report(unraisable):
                current(unraisable)
        hook.drops_closed_loop_reports = True
        sys.unraisablehook = hook
    asyncio_log = logging.getLogger("asyncio")
    if not any(isinstance(f, _LateFutureFilter) for f in asyncio_log.filters):
        asyncio_log.addFilter(_LateFutureFilter())


def _one_line(err: BaseException, limit: int = 300) -> str:
    """First line of ``str(err)`` (at most ``limit`` characters), or the exception's type name."""
    text = str(err).strip().splitlines()
    line = (text[0].strip() if text else "") or type(err).__name__
    return line if len(line) <= limit else line[:limit - 3] + "..."


def _check_json(path: str, step_dir: str) -> None:
    rel = os.path.relpath(path, step_dir)
    if not os.path.isfile(path):
        raise CheckpointError(f"{step_dir}: missing metadata file {rel} (incomplete or damaged checkpoint)")
    try:
        with open(path, encoding="utf-8") as f:
            json.load(f)
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise CheckpointError(f"{step_dir}: corrupt metadata file {rel} ({_one_line(e)})") from None


def check_step_dir(step_dir: str, items: tuple[str, ...] = ("state", "extra")) -> None:
    """Raise :class:`CheckpointError` unless ``step_dir`` looks like a complete checkpoint of ``items``.

    Checks (cheap, no array is read): the folder is not empty, no file in it has zero bytes, and the
    step's and each item's orbax metadata files exist and parse as JSON.
    """
    if not os.path.isdir(step_dir):
        raise CheckpointError(f"{step_dir}: checkpoint folder does not exist")
    files = [os.path.join(root, f) for root, _, names in os.walk(step_dir) for f in names]
    if not files:
        raise CheckpointError(f"{step_dir}: empty checkpoint folder (an interrupted save? delete it to "
                              "use an earlier checkpoint)")
    for path in sorted(files):
        if os.path.getsize(path) == 0:
            raise CheckpointError(f"{step_dir}: file {os.path.relpath(path, step_dir)} is empty (0 bytes)")
    _check_json(os.path.join(step_dir, _STEP_METADATA), step_dir)
    for item in items:
        if not os.path.isdir(os.path.join(step_dir, item)):
            raise CheckpointError(f"{step_dir}: no '{item}' item in the checkpoint")
        _check_json(os.path.join(step_dir, item, _ITEM_METADATA[item]), step_dir)



def _is_key(x: Any) -> bool:
    dtype = getattr(x, "dtype", None)
    return dtype is not None and jax.dtypes.issubdtype(dtype, jax.dtypes.prng_key)


def _to_host(x: Any) -> Any:
    """Leaf -> host numpy copy (keys -> their uint32 data)."""
    if _is_key(x):
        x = jax.random.key_data(x)
    return np.array(x, copy=True)


def _abstract(x: Any) -> jax.ShapeDtypeStruct:
    """Target leaf (array or ShapeDtypeStruct) -> restore spec, placed like the target or on local device 0."""
    if _is_key(x):
        data = jax.eval_shape(jax.random.key_data, jax.ShapeDtypeStruct(x.shape, x.dtype))
        shape, dtype = data.shape, data.dtype
    else:
        shape = tuple(x.shape) if hasattr(x, "shape") else np.shape(x)
        dtype = x.dtype if hasattr(x, "dtype") else jnp.result_type(x)
    sharding = getattr(x, "sharding", None)
    if sharding is None or _is_key(x):
        sharding = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
    return jax.ShapeDtypeStruct(shape, dtype, sharding=sharding)


def _key_impl(x: Any) -> Any:
    if isinstance(x, jax.Array):
        return jax.random.key_impl(x)
    # ShapeDtypeStruct of a key dtype: jax 0.10 has no public accessor; None -> default impl.
    return getattr(x.dtype, "_impl", None)


def _from_restored(restored: Any, target: Any) -> Any:
    if _is_key(target):
        return jax.random.wrap_key_data(restored, impl=_key_impl(target))
    return restored


def _remove_unfinished(directory: str) -> None:
    """Delete ``*.orbax-checkpoint-tmp*`` folders left by a killed save (primary process only), synchronously."""
    if jax.process_index() != 0 or not os.path.isdir(directory):
        return
    for name in os.listdir(directory):
        if ".orbax-checkpoint-tmp" in name:
            shutil.rmtree(os.path.join(directory, name), ignore_errors=True)


class Checkpointer:
    """Keeps the last ``max_to_keep`` checkpoints of a run under ``directory``.

    Args:
        directory: checkpoint root (created if missing; relative paths are made absolute).
        max_to_keep: number of most recent checkpoints kept on disk (``None`` keeps all).
        save_every: ``save(step, ...)`` only writes when ``step % save_every == 0`` (or ``force=True``).
        async_save: write in a background thread (host copy is still synchronous).
    """

    def __init__(self, directory: str | os.PathLike, max_to_keep: int | None = 3, save_every: int = 1,
                 async_save: bool = True):
        if save_every < 1:
            raise ValueError(f"save_every must be >= 1, got {save_every}")
        self.directory = os.path.abspath(os.path.expanduser(os.fspath(directory)))
        self.save_every = int(save_every)
        _remove_unfinished(self.directory)     # orbax's own clean-up runs in a thread that can outlive close()
        options = ocp.CheckpointManagerOptions(
            max_to_keep=max_to_keep, create=True, cleanup_tmp_directories=False,
            enable_async_checkpointing=async_save)
        with _quiet():
            self._manager = ocp.CheckpointManager(self.directory, options=options, item_names=("state", "extra"))

    def should_save(self, step: int) -> bool:
        """True when ``step`` is a multiple of ``save_every``."""
        return step % self.save_every == 0

    def save(self, step: int, pytree_state: Any, extra_json: dict | None = None, force: bool = False) -> bool:
        """Save ``pytree_state`` (any pytree of arrays / PRNG keys) and the JSON dict ``extra_json``.

        Returns True if a checkpoint was written (False when skipped by ``save_every`` or because the
        step is already on disk).  Returns once the arrays are copied to host; the write is async.
        """
        step = int(step)
        if not (force or self.should_save(step)) or step in self.all_steps():
            return False
        host = jax.tree.map(_to_host, pytree_state)
        args = ocp.args.Composite(state=ocp.args.StandardSave(host),
                                  extra=ocp.args.JsonSave(dict(extra_json or {})))
        with _quiet():
            return bool(self._manager.save(step, args=args, force=True))

    def latest_step(self, required: bool = False) -> int | None:
        """Most recent *finished* checkpoint step; None if there is none (``required``: CheckpointError)."""
        with _quiet():
            step = self._manager.latest_step()
        if step is None and required:
            raise CheckpointError(f"{self.directory}: no checkpoint found (expected <step>/ folders written "
                                  "by training)")
        return step

    def all_steps(self) -> list[int]:
        """Sorted steps of all finished checkpoints on disk."""
        with _quiet():
            return sorted(self._manager.all_steps())

    def _step_dir(self, step: int | None, items: tuple[str, ...]) -> tuple[int, str]:
        """``(step, folder)`` of a checkpoint that passed :func:`check_step_dir`; None = latest."""
        if step is None:
            step = self.latest_step(required=True)
        step = int(step)
        if step not in self.all_steps():
            avail = ", ".join(map(str, self.all_steps())) or "none"
            raise CheckpointError(f"{self.directory}: no checkpoint for step {step} (available: {avail})")
        step_dir = os.path.join(self.directory, str(step))
        check_step_dir(step_dir, items)
        return step, step_dir

    def _restore(self, step: int | None, item: str, arg: Any) -> Any:
        step, step_dir = self._step_dir(step, (item,))
        try:
            with _quiet():
                out = self._manager.restore(step, args=ocp.args.Composite(**{item: arg}))
        except (ValueError, KeyError, OSError, TypeError) as e:
            raise CheckpointError(f"{step_dir}: cannot restore '{item}': {_one_line(e)}") from None
        return out[item]

    def restore(self, step: int | None, target_pytree: Any) -> Any:
        """Restore the ``state`` item of ``step`` (None: the latest) into the structure of ``target_pytree``.

        Args:
            target_pytree: pytree of arrays or ``jax.ShapeDtypeStruct`` (e.g. ``jax.eval_shape(init_fn, key)``)
                with the same structure as what was saved; PRNG-key leaves come back as typed keys.
        Returns:
            A pytree of ``jax.Array`` with the structure, shapes and dtypes of ``target_pytree``.
        Raises:
            CheckpointError: no such checkpoint, a damaged one, or one that does not match the target.
        """
        abstract = jax.tree.map(_abstract, target_pytree)
        state = self._restore(step, "state", ocp.args.StandardRestore(abstract))
        return jax.tree.map(_from_restored, state, target_pytree)

    def restore_extra(self, step: int | None) -> dict:
        """The JSON dict saved with ``step`` (``extra_json``; None: the latest); raises like ``restore``."""
        return dict(self._restore(step, "extra", ocp.args.JsonRestore()) or {})

    def wait(self) -> None:
        """Block until pending async saves are on disk."""
        with _quiet():
            self._manager.wait_until_finished()

    def close(self) -> None:
        """Wait for pending saves and release the manager's resources."""
        with _quiet():
            self._manager.wait_until_finished()
            self._manager.close()

    def __enter__(self) -> "Checkpointer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
