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
"""

from __future__ import annotations

import os
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp

__all__ = ["Checkpointer"]


def _is_key(x: Any) -> bool:
    dtype = getattr(x, "dtype", None)
    return dtype is not None and jax.dtypes.issubdtype(dtype, jax.dtypes.prng_key)


def _to_host(x: Any) -> Any:
    """Leaf -> host numpy copy (keys -> their uint32 data)."""
    if _is_key(x):
        x = jax.random.key_data(x)
    return np.array(x, copy=True)


def _abstract(x: Any) -> jax.ShapeDtypeStruct:
    """Target leaf (array or ShapeDtypeStruct) -> restore spec, placed like the target or on device 0."""
    if _is_key(x):
        data = jax.eval_shape(jax.random.key_data, jax.ShapeDtypeStruct(x.shape, x.dtype))
        shape, dtype = data.shape, data.dtype
    else:
        shape = tuple(x.shape) if hasattr(x, "shape") else np.shape(x)
        dtype = x.dtype if hasattr(x, "dtype") else jnp.result_type(x)
    sharding = getattr(x, "sharding", None)
    if sharding is None or _is_key(x):
        sharding = jax.sharding.SingleDeviceSharding(jax.devices()[0])
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
        options = ocp.CheckpointManagerOptions(
            max_to_keep=max_to_keep, create=True, cleanup_tmp_directories=True,
            enable_async_checkpointing=async_save)
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
        if not (force or self.should_save(step)) or step in self._manager.all_steps():
            return False
        host = jax.tree.map(_to_host, pytree_state)
        args = ocp.args.Composite(state=ocp.args.StandardSave(host),
                                  extra=ocp.args.JsonSave(dict(extra_json or {})))
        return bool(self._manager.save(step, args=args, force=True))

    def latest_step(self) -> int | None:
        """Most recent *finished* checkpoint step, or None if there is none."""
        return self._manager.latest_step()

    def all_steps(self) -> list[int]:
        """Sorted steps of all finished checkpoints on disk."""
        return sorted(self._manager.all_steps())

    def restore(self, step: int, target_pytree: Any) -> Any:
        """Restore the ``state`` item of ``step`` into the structure of ``target_pytree``.

        Args:
            target_pytree: pytree of arrays or ``jax.ShapeDtypeStruct`` (e.g. ``jax.eval_shape(init_fn, key)``)
                with the same structure as what was saved; PRNG-key leaves come back as typed keys.
        Returns:
            A pytree of ``jax.Array`` with the structure, shapes and dtypes of ``target_pytree``.
        """
        abstract = jax.tree.map(_abstract, target_pytree)
        out = self._manager.restore(int(step), args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract)))
        return jax.tree.map(_from_restored, out.state, target_pytree)

    def restore_extra(self, step: int) -> dict:
        """The JSON dict saved with ``step`` (``extra_json``)."""
        out = self._manager.restore(int(step), args=ocp.args.Composite(extra=ocp.args.JsonRestore()))
        return dict(out.extra or {})

    def wait(self) -> None:
        """Block until pending async saves are on disk."""
        self._manager.wait_until_finished()

    def close(self) -> None:
        """Wait for pending saves and release the manager's resources."""
        self._manager.wait_until_finished()
        self._manager.close()

    def __enter__(self) -> "Checkpointer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
