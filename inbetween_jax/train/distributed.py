"""Multi-process training on JAX's multi-controller runtime (``jax.distributed``).

Every process runs the same program.  After :func:`initialize`, ``jax.devices()`` lists the devices of
all processes, :func:`global_mesh` is a 1-D data mesh over them, and ``run_training`` (``train.loop``)
detects ``jax.process_count() > 1`` by itself: each process builds the global batch with the
deterministic ``batch_fn``, keeps the rows of its own devices and the global array is assembled with
``jax.make_array_from_process_local_data`` (``train.parallel.shard_batch``); the state is replicated,
orbax writes each checkpoint once (primary process), only process 0 writes metrics and shows progress.

Launch:

* cluster launcher (SLURM ``srun``, Open MPI ``mpirun``, Kubernetes indexed Jobs / JobSets, Cloud TPU
  pods, or ``JAX_COORDINATOR_ADDRESS`` set by hand): call ``initialize()`` without arguments first thing
  in the program; JAX finds the coordinator, the process count and this process's id.
* one machine (a check of the multi-process path): ``launch_local(N, argv)`` starts N copies of
  ``python -m <module> argv...`` with ``INBETWEEN_COORDINATOR`` (``host:port``),
  ``INBETWEEN_NUM_PROCESSES`` and ``INBETWEEN_PROCESS_ID`` set; ``initialize()`` in each copy reads them.

CPU: cross-process collectives use gloo, the default of ``jax_cpu_collectives_implementation`` in
jax 0.10 (nothing to configure; ``"mpi"`` is the alternative).  Each CPU process has one device unless
``XLA_FLAGS=--xla_force_host_platform_device_count=K`` is set.
"""
from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from typing import Callable, Mapping, Sequence

import jax

__all__ = ["ENV_COORDINATOR", "ENV_NUM_PROCESSES", "ENV_PROCESS_ID", "initialize", "launch_local",
           "global_mesh", "is_primary", "requested_processes"]

ENV_COORDINATOR = "INBETWEEN_COORDINATOR"
ENV_NUM_PROCESSES = "INBETWEEN_NUM_PROCESSES"
ENV_PROCESS_ID = "INBETWEEN_PROCESS_ID"


def _env_int(name: str) -> int | None:
    text = os.environ.get(name)
    if text is None or not text.strip():
        return None
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"environment variable {name}={text!r} is not an integer") from None


def requested_processes() -> int:
    """Process count asked for by ``INBETWEEN_NUM_PROCESSES`` (1 when unset)."""
    return _env_int(ENV_NUM_PROCESSES) or 1


def _cluster_launcher() -> str | None:
    """Name of a multi-process launcher JAX can auto-configure from the environment, or None."""
    env = os.environ
    if all(v in env for v in ("SLURM_JOB_ID", "SLURM_STEP_NODELIST", "SLURM_NTASKS", "SLURM_PROCID",
                              "SLURM_LOCALID")) and int(env["SLURM_NTASKS"]) > 1:
        return "SLURM"
    if "OMPI_MCA_orte_hnp_uri" in env and int(env.get("OMPI_COMM_WORLD_SIZE", "2")) > 1:
        return "Open MPI"
    if "KUBERNETES_SERVICE_HOST" in env and "JOB_COMPLETION_INDEX" in env:
        return "Kubernetes"
    if "," in env.get("TPU_PROCESS_ADDRESSES", env.get("TPU_WORKER_HOSTNAMES", "")):
        return "Cloud TPU"
    if env.get("JAX_COORDINATOR_ADDRESS"):
        return "JAX_COORDINATOR_ADDRESS"
    return None


def initialize(num_processes: int | None = None, process_id: int | None = None,
               coordinator: str | None = None) -> tuple[int, int]:
    """Join the multi-process runtime; returns ``(jax.process_index(), jax.process_count())``.

    Arguments default to ``INBETWEEN_NUM_PROCESSES`` / ``INBETWEEN_PROCESS_ID`` / ``INBETWEEN_COORDINATOR``
    (``host:port``; set by :func:`launch_local`).  When none is given and a cluster launcher is detected
    (SLURM, Open MPI, Kubernetes, Cloud TPU pod, ``JAX_COORDINATOR_ADDRESS``), JAX configures itself
    from that launcher; missing pieces of a partial explicit setting are auto-detected the same way.
    One process (nothing set, or a count of 1) is a no-op.  Must run before any JAX computation;
    calling it again after a successful initialisation is a no-op.
    """
    if jax.distributed.is_initialized():
        return jax.process_index(), jax.process_count()
    num_processes = _env_int(ENV_NUM_PROCESSES) if num_processes is None else int(num_processes)
    process_id = _env_int(ENV_PROCESS_ID) if process_id is None else int(process_id)
    coordinator = coordinator or os.environ.get(ENV_COORDINATOR) or None
    if num_processes is not None and num_processes < 1:
        raise ValueError(f"the number of processes must be >= 1, got {num_processes}")
    if num_processes == 1:
        return 0, 1
    if num_processes is None and process_id is None and coordinator is None and _cluster_launcher() is None:
        return 0, 1
    try:
        jax.distributed.initialize(coordinator, num_processes, process_id)
    except ValueError as e:
        raise ValueError(f"cannot start {num_processes or 'several'} processes: {e} (set {ENV_COORDINATOR}, "
                         f"{ENV_NUM_PROCESSES} and {ENV_PROCESS_ID}, or use a cluster launcher)") from None
    return jax.process_index(), jax.process_count()


def is_primary() -> bool:
    """True on the process that prints and writes logs (``jax.process_index() == 0``)."""
    return jax.process_index() == 0


def global_mesh(axis: str = "data"):
    """1-D data mesh over ``jax.devices()`` of all processes (``train.parallel.make_mesh()``)."""
    from .parallel import make_mesh
    return make_mesh(axis=axis)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _stop(procs: Sequence[subprocess.Popen], grace_s: float) -> None:
    """SIGINT the running children, then SIGKILL those still alive after ``grace_s`` seconds.

    SIGKILL is needed in practice: a process blocked in a collective waits for its dead peers (JAX also
    catches SIGTERM as a preemption notice), so it would not exit by itself.
    """
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    deadline = time.monotonic() + grace_s
    for p in procs:
        try:
            p.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _to_stderr(line: str) -> None:
    print(line, file=sys.stderr)


def _exit_code(rc: int) -> int:
    return 128 - rc if rc < 0 else rc      # killed by signal s -> 128 + s, as a shell reports it


@contextlib.contextmanager
def sigint_unblocked():
    """SIGINT unblocked in the calling thread while children are started, so they inherit an unblocked mask: the
    CLI's Ctrl-C watcher (:mod:`inbetween_jax.cli.interrupt`) blocks SIGINT in the launcher, and a child would
    inherit that and never see the SIGINT it is stopped with.  Done around ``Popen`` rather than in a
    ``preexec_fn``, which makes Python fork a multithreaded JAX process (JAX warns of it)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def launch_local(num_processes: int, argv: Sequence[str], module: str = "inbetween_jax.cli",
                 env: Mapping[str, str] | None = None, grace_s: float = 5.0,
                 on_interrupt: Callable[[Callable[[], None]], None] | None = None,
                 report: Callable[[str], None] = _to_stderr) -> int:
    """Run ``python -m module *argv`` as ``num_processes`` cooperating local processes; returns an exit code.

    Each child gets ``INBETWEEN_COORDINATOR=127.0.0.1:<free port>``, ``INBETWEEN_NUM_PROCESSES`` and
    ``INBETWEEN_PROCESS_ID`` (plus ``env``) and must call :func:`initialize` before using JAX.  Process 0
    keeps this terminal's stdout / stderr; the others are quiet (stdout discarded, stderr shown only if
    that process fails).  When a process fails the others are stopped and its exit code is returned
    (the first non-zero one); Ctrl-C stops all of them and returns 130; otherwise 0.

    Every child sees all local devices: on a machine with accelerators pass ``env={"JAX_PLATFORMS": "cpu"}``
    for a CPU check (a single process already drives all local accelerators through the mesh).

    ``on_interrupt(stop)`` is given, before any child starts, the function that stops them (SIGINT, SIGKILL
    after ``grace_s``): the CLI passes its Ctrl-C watcher's :func:`inbetween_jax.cli.interrupt.at_exit`, since
    the watcher ends the launcher without returning here.  ``report(line)`` prints a failed child's stderr lines.
    """
    n = int(num_processes)
    if n < 1:
        raise ValueError(f"the number of processes must be >= 1, got {num_processes}")
    base = dict(os.environ, **(env or {}))
    base.update({ENV_COORDINATOR: f"127.0.0.1:{_free_port()}", ENV_NUM_PROCESSES: str(n)})
    cmd = [sys.executable, "-m", module, *map(str, argv)]
    procs: list[subprocess.Popen] = []
    logs: list = []
    if on_interrupt is not None:
        on_interrupt(lambda: _stop(procs, grace_s))
    try:
        for pid in range(n):
            child_env = dict(base, **{ENV_PROCESS_ID: str(pid)})
            quiet = {}
            if pid > 0:
                logs.append(tempfile.TemporaryFile())
                quiet = {"stdout": subprocess.DEVNULL, "stderr": logs[-1]}
            with sigint_unblocked():
                procs.append(subprocess.Popen(cmd, env=child_env, **quiet))
        while True:
            codes = [p.poll() for p in procs]
            failed = [(pid, c) for pid, c in enumerate(codes) if c not in (None, 0)]
            if failed:
                pid, code = failed[0]
                _stop(procs, grace_s)
                if pid > 0:
                    logs[pid - 1].seek(0)
                    tail = logs[pid - 1].read()[-4000:].decode(errors="replace").rstrip()
                    if tail:
                        report("\n".join(f"[process {pid}] {line}" for line in tail.splitlines()))
                return _exit_code(code)
            if all(c == 0 for c in codes):
                return 0
            time.sleep(0.05)
    except KeyboardInterrupt:
        _stop(procs, grace_s)
        return 130
    finally:
        _stop(procs, 0.0)
        for f in logs:
            f.close()
