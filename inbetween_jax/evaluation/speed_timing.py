"""Timing helpers of the speed section (:mod:`inbetween_jax.evaluation.speed`): compile times cold and from the
persistent cache, calls timed side by side in rotating rounds, and JAX's training step against a PyTorch
reference in eager mode and under each ``torch.compile`` backend (a first call past :data:`COMPILE_TIMEOUT_S`
counts as not compiling)."""
from __future__ import annotations

import sys
import time

import numpy as np

__all__ = ["TORCH_BACKENDS", "COMPILE_TIMEOUT_S", "compile_pair", "first_call_s", "side_by_side", "compare_steps"]


def compile_pair(jitted, *args):
    """(cold seconds with the persistent cache off, seconds when served from a fresh persistent cache)."""
    import jax

    from inbetween_jax.profiling import compile_seconds
    jax.config.update("jax_enable_compilation_cache", False)
    jax.clear_caches()
    cold = compile_seconds(jitted, *args)
    jax.config.update("jax_enable_compilation_cache", True)
    jax.clear_caches()
    compile_seconds(jitted, *args)          # writes the entry
    jax.clear_caches()
    cached = compile_seconds(jitted, *args)
    return cold, cached


TORCH_BACKENDS = ("inductor", "aot_eager")      # torch.compile backends tried, in order of preference
COMPILE_TIMEOUT_S = 300                         # a backend that needs longer counts as not compiling


def first_call_s(step, timeout_s=COMPILE_TIMEOUT_S) -> float:
    """Seconds of ``step()``'s first call (torch.compile compiles there); TimeoutError past ``timeout_s``."""
    import signal
    import threading

    fired = []

    def _stop(*_):
        fired.append(True)
        raise TimeoutError(f"no compiled step within {timeout_s} s")

    alarm = hasattr(signal, "SIGALRM") and threading.current_thread() is threading.main_thread()
    if alarm:
        old = signal.signal(signal.SIGALRM, _stop)
        signal.alarm(int(timeout_s))
    t0 = time.perf_counter()
    try:
        step()
    except Exception as e:      # inductor re-raises the alarm inside a worker wait as its own error
        if fired:
            raise TimeoutError(f"no compiled step within {timeout_s} s") from e
        raise
    finally:
        if alarm:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, old)
    return time.perf_counter() - t0


def side_by_side(fns: dict, reps: int, warmup: int = 1) -> dict:
    """ms of each call of ``fns[name]()`` over ``reps`` rounds ({name: [ms, ...]}); each round calls every function
    once, in turn (the order rotates), so a change in machine load hits all of them alike.  Blocked on results."""
    from inbetween_jax.profiling import block
    names = list(fns)
    for n in names:
        for _ in range(warmup):
            block(fns[n]())
    times = {n: [] for n in names}
    for r in range(reps):
        for n in names[r % len(names):] + names[:r % len(names)]:
            t0 = time.perf_counter()
            block(fns[n]())
            times[n].append(round((time.perf_counter() - t0) * 1e3, 1))
    return times


def compare_steps(out: dict, jax_call, make_torch, reps: int) -> None:
    """JAX's step against PyTorch eager and ``torch.compile`` (each backend of :data:`TORCH_BACKENDS`), timed side
    by side; fills ``jax_step_ms`` [, ``torch_step_ms``, ``torch_compile_step_ms`` / ``_backend`` / ``_s`` (the
    first backend that compiled; its first call, compile + one step), ``torch_compile_tries``] and ``calls_ms``
    (every timed call).  make_torch: ``backend or None -> step closure``, or None (no torch)."""
    fns, tries = {"jax": jax_call}, {}
    if make_torch is not None:
        fns["torch"] = make_torch(None)
        for be in TORCH_BACKENDS:
            try:
                step = make_torch(be)
                tries[be] = {"compile_s": first_call_s(step)}
                fns[be] = step
            except Exception as e:                      # noqa: BLE001 -- any failure means "does not compile"
                tries[be] = {"error": f"{type(e).__name__}: {(str(e).strip().splitlines() or [''])[0][:160]}"}
                if "torch._dynamo" in sys.modules:    # a half-done compile leaves no state behind
                    sys.modules["torch._dynamo"].reset()
    out["calls_ms"] = side_by_side(fns, max(5, reps))
    med = {n: float(np.median(t)) for n, t in out["calls_ms"].items()}
    out["jax_step_ms"] = med["jax"]
    if make_torch is None:
        return
    out["torch_step_ms"] = med["torch"]
    for be in tries:
        if be in med:
            tries[be]["step_ms"] = med[be]
    ok = [be for be in TORCH_BACKENDS if "step_ms" in tries[be]]
    if ok:
        out.update(torch_compile_step_ms=tries[ok[0]]["step_ms"], torch_compile_backend=ok[0],
                   torch_compile_s=tries[ok[0]]["compile_s"])
    out["torch_compile_tries"] = tries
