"""Data-parallel training over several devices with ``jax.sharding`` (single program, SPMD).

The train state is replicated on every device of a 1-D mesh and the batch is split along its leading
axis.  The pure ``train_step_fn(state, batch, key)`` is unchanged: its loss is a mean over the *global*
batch, so when it is jitted with a sharded batch and a replicated output state, XLA partitions the
forward / backward pass and inserts the gradient all-reduce itself.  Same seed -> the same run as on
one device up to float summation order.

    mesh = make_mesh()                       # all devices, axis "data"
    run_training(init_fn, step_fn, batch_fn, cfg, run_dir, n, mesh=mesh)

On CPU several host devices can be faked with ``XLA_FLAGS=--xla_force_host_platform_device_count=N``
(set before JAX is imported).

Several processes (``train.distributed``): the mesh spans ``jax.devices()`` of all processes.  Every
process builds the same global batch and keeps the rows of its own devices, which
``jax.make_array_from_process_local_data`` assembles into one global array; the state is replicated
from each process's identical host copy.  The global batch is therefore bitwise the one of a
single-process run.
"""
from __future__ import annotations

from typing import Any, Callable

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from .step import step_body

__all__ = ["make_mesh", "shard_batch", "replicate", "make_parallel_step_fn", "local_rows"]


def make_mesh(num_devices: int | None = None, axis: str = "data") -> Mesh:
    """1-D mesh over the first ``num_devices`` devices (default: all of ``jax.devices()``, every process's)."""
    devices = jax.devices()
    n = len(devices) if num_devices is None else int(num_devices)
    if not 1 <= n <= len(devices):
        raise ValueError(f"asked for a mesh over {n} devices but only {len(devices)} are available")
    return Mesh(np.asarray(devices[:n]), (axis,))


def _axis(mesh: Mesh) -> str:
    if len(mesh.axis_names) != 1:
        raise ValueError(f"expected a 1-D mesh, got axes {mesh.axis_names}")
    return mesh.axis_names[0]


def shard_batch(batch: Any, mesh: Mesh) -> Any:
    """Split the leading axis of every array leaf across the mesh; 0-d leaves are replicated.

    Args:
        batch: pytree of arrays (NumPy or JAX), each (B, ...) with one common B, or 0-d scalars.
        mesh: 1-D mesh with D devices.
    Returns:
        The same pytree of ``jax.Array``: (B, ...) leaves on ``NamedSharding(mesh, P(axis))`` (B / D rows
        per device), scalars on ``NamedSharding(mesh, P())``.
    Raises:
        ValueError: when a leading dimension is not divisible by D (the message names both numbers).
    """
    axis = _axis(mesh)
    n = mesh.size
    split, rep = NamedSharding(mesh, P(axis)), NamedSharding(mesh, P())
    local = _is_local(mesh)

    def put(x):
        if np.ndim(x) == 0:
            return jax.device_put(x, rep) if local else _global(x, rep)
        b = np.shape(x)[0]
        if b % n:
            raise ValueError(f"batch size {b} is not divisible by the number of devices {n} "
                             f"(mesh axis '{axis}'); use a batch size that is a multiple of {n}")
        if local:
            return jax.device_put(x, split)
        if isinstance(x, jax.Array) and x.sharding == split:
            return x
        return jax.make_array_from_process_local_data(split, local_rows(x, split), np.shape(x))

    return jax.tree.map(put, batch)


def _is_local(mesh: Mesh) -> bool:
    """True when this process addresses every device of ``mesh`` (always so for one process)."""
    return all(d.process_index == jax.process_index() for d in mesh.devices.flat)


def local_rows(x: Any, sharding: NamedSharding) -> np.ndarray:
    """The rows of the global (B, ...) array ``x`` that live on this process's devices, in device order.

    Returns (B_local, ...): the concatenation of the distinct row blocks of the addressable devices,
    sorted by their first row -- the ``local_data`` layout ``jax.make_array_from_process_local_data``
    expects.
    """
    x = np.asarray(x)
    starts = sorted({(idx[0].start or 0, idx[0].stop if idx[0].stop is not None else x.shape[0])
                     for idx in sharding.addressable_devices_indices_map(x.shape).values()})
    return np.concatenate([x[a:b] for a, b in starts], axis=0)


def _global(x: Any, rep: NamedSharding) -> jax.Array:
    """Host value (identical on every process) -> array replicated over a multi-process mesh."""
    if isinstance(x, jax.Array) and jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key):
        data = _global(jax.random.key_data(x), rep)
        return jax.random.wrap_key_data(data, impl=jax.random.key_impl(x))
    host = np.asarray(x)
    return jax.make_array_from_process_local_data(rep, host, host.shape)


def replicate(state: Any, mesh: Mesh) -> Any:
    """Copy every leaf of ``state`` (arrays, typed PRNG keys) onto all devices of ``mesh``.

    With several processes every process must pass the same values (e.g. the same init / restore).
    """
    rep = NamedSharding(mesh, P())
    if _is_local(mesh):
        return jax.device_put(state, rep)
    return jax.tree.map(lambda x: _global(x, rep), state)


def make_parallel_step_fn(train_step_fn: Callable, train_base: jax.Array, mesh: Mesh) -> Callable:
    """Data-parallel twin of :func:`inbetween_jax.train.make_step_fn`: ``(state, batch, i) -> (state, metrics)``.

    ``state`` (donated) and the returned state / metrics are replicated over ``mesh``; ``batch`` is
    placed with :func:`shard_batch` (a no-op when it already is).  The step key is
    ``fold_in(train_base, i)``, as on one device.
    """
    rep = NamedSharding(mesh, P())
    jitted = jax.jit(step_body(train_step_fn), in_shardings=(rep, None, rep, rep),
                     out_shardings=(rep, rep), donate_argnums=0)
    base = replicate(train_base, mesh)

    def step(state, batch, i):
        return jitted(state, shard_batch(batch, mesh), i, base)

    return step
