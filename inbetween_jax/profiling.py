"""Benchmark helpers: wall-clock medians, compile times and a matmul FLOP counter for jaxprs.

XLA's own cost analysis counts the body of a ``lax.scan`` (a while loop) once, whatever its trip count,
so it under-counts every recurrent model here.  :func:`matmul_flops` walks the jaxpr instead and
multiplies each scan body by its length; it counts the multiply-adds of ``dot_general`` and
``conv_general_dilated`` (2 FLOPs each), which is what is compared with the measured matmul peak.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Sequence

import jax
import jax.extend.core as jex
import jax.numpy as jnp
import numpy as np

__all__ = ["block", "time_calls", "median_ms", "compile_seconds", "matmul_flops", "matmul_peak_flops",
           "op_ms_by_kind"]


def block(x: Any) -> Any:
    """Wait for every array in a pytree (JAX dispatch is asynchronous)."""
    return jax.tree.map(lambda a: a.block_until_ready() if hasattr(a, "block_until_ready") else a, x)


def time_calls(fn: Callable[[], Any], reps: int = 10, warmup: int = 1, min_seconds: float = 0.0) -> list:
    """Seconds of ``reps`` calls of ``fn()`` (results blocked on), after ``warmup`` untimed calls.

    Keeps calling past ``reps`` until ``min_seconds`` of timed calls have passed.  Returns a list of floats.
    """
    for _ in range(warmup):
        block(fn())
    out, total = [], 0.0
    while len(out) < reps or total < min_seconds:
        t0 = time.perf_counter()
        block(fn())
        out.append(time.perf_counter() - t0)
        total += out[-1]
    return out


def median_ms(times: Sequence[float]) -> float:
    return float(np.median(np.asarray(times)) * 1e3)


def compile_seconds(jitted, *args, **kwargs) -> float:
    """Seconds to trace, lower and compile ``jitted`` for these arguments (no execution)."""
    t0 = time.perf_counter()
    jitted.lower(*args, **kwargs).compile()
    return time.perf_counter() - t0


def _dot_flops(eqn) -> float:
    (lc, _), _ = eqn.params["dimension_numbers"]
    lhs = eqn.invars[0].aval.shape
    out = eqn.outvars[0].aval.shape
    return 2.0 * math.prod(out) * math.prod(lhs[d] for d in lc)


def _conv_flops(eqn) -> float:
    rhs = eqn.invars[1].aval.shape
    out = eqn.outvars[0].aval.shape
    dn = eqn.params["dimension_numbers"]
    cout = rhs[dn.rhs_spec[0]]
    return 2.0 * math.prod(out) * math.prod(rhs) / cout


def _sub_jaxprs(value):
    vals = value if isinstance(value, (tuple, list)) else (value,)
    for v in vals:
        if isinstance(v, jex.ClosedJaxpr):
            yield v.jaxpr
        elif isinstance(v, jex.Jaxpr):
            yield v


def _count(jaxpr) -> float:
    total = 0.0
    for eqn in jaxpr.eqns:
        name = eqn.primitive.name
        if name == "dot_general":
            total += _dot_flops(eqn)
        elif name == "conv_general_dilated":
            total += _conv_flops(eqn)
        elif name == "scan":
            total += eqn.params["length"] * _count(eqn.params["jaxpr"].jaxpr)
        elif name == "cond":
            total += max(_count(b.jaxpr) for b in eqn.params["branches"])
        else:  # jit / pjit, custom_vjp / custom_jvp calls, remat, while (counted once): recurse
            for value in eqn.params.values():
                for sub in _sub_jaxprs(value):
                    total += _count(sub)
    return total


def matmul_flops(fn: Callable, *args, **kwargs) -> float:
    """Matmul + conv FLOPs of one call of ``fn(*args)`` (scan bodies times their length)."""
    return _count(jax.make_jaxpr(fn)(*args, **kwargs).jaxpr)


def matmul_peak_flops(n: int = 1024, reps: int = 20) -> float:
    """Measured float32 ``n x n @ n x n`` throughput of this device (FLOP/s, median of ``reps``)."""
    a = jax.random.normal(jax.random.key(0), (n, n), jnp.float32)
    b = jax.random.normal(jax.random.key(1), (n, n), jnp.float32)
    f = jax.jit(lambda x, y: x @ y)
    times = time_calls(lambda: f(a, b), reps=reps, warmup=2)
    return 2.0 * n ** 3 / float(np.median(times))


_OP_NAME = r"[a-z][a-z0-9_-]*"      # XLA op names; runtime spans and Python frames have capitals, spaces, '$', ':'


def op_ms_by_kind(fn: Callable[[], Any], calls: int = 5, trace_dir: str | None = None) -> tuple:
    """Where the time of ``fn()`` goes, from a :mod:`jax.profiler` trace of ``calls`` calls (after one untimed).

    Returns ``(wall ms per call under the profiler, {op kind: ms per call}, covered ms per call)``: kinds are
    XLA's op names without their ``.N`` suffix (``transpose_copy_fusion``, ``conv_general_dilated``, ...), largest
    first, summed over threads (so they can exceed the wall time); ``covered`` is the time during which some op
    ran (the union of their intervals).  Work an op hands to threads the trace does not follow shows in neither.
    """
    import collections
    import glob
    import gzip
    import json
    import re
    import shutil
    import tempfile
    block(fn())
    folder = trace_dir or tempfile.mkdtemp(prefix="op_ms_")
    try:
        with jax.profiler.trace(folder, create_perfetto_trace=True):
            t0 = time.perf_counter()
            for _ in range(calls):
                block(fn())
            wall = (time.perf_counter() - t0) / calls * 1e3
        path = glob.glob(f"{folder}/**/*.trace.json.gz", recursive=True)[0]
        with gzip.open(path) as f:
            trace = json.load(f)
    finally:
        if trace_dir is None:
            shutil.rmtree(folder, ignore_errors=True)
    events = trace["traceEvents"] if isinstance(trace, dict) else trace
    kinds, spans = collections.Counter(), []
    for e in events:
        op = re.fullmatch(rf"({_OP_NAME})(\.\d+)?", e.get("name", ""))
        if e.get("ph") == "X" and "dur" in e and op:
            kinds[op.group(1)] += e["dur"] / 1e3 / calls
            spans.append((e["ts"], e["ts"] + e["dur"]))
    covered, end = 0.0, -np.inf
    for a, b in sorted(spans):                       # union of the op intervals (microseconds)
        covered += max(b - max(a, end), 0.0)
        end = max(end, b)
    return wall, dict(kinds.most_common()), covered / 1e3 / calls
