"""A faster ``malloc`` for the ``inbetween`` command, where the machine has one (docs/results/speed.md, "malloc").

XLA:CPU allocates and frees the temporaries of every compiled call through ``malloc``.  glibc's per-thread arenas
hand those pages back to the kernel and fault them in again on the next call: about 33,000 minor page faults and
90 ms of system CPU per S-CVAE ``cpu``-width training step of about 220 ms on this project's 2-core machines
(``experiments/malloc_speed.py``).  tcmalloc (Debian's ``libtcmalloc-minimal4``) and jemalloc (``libjemalloc2``,
with its page decay off) keep the pages; under tcmalloc the training steps run 1.1-1.35x faster (CAE 1.35x,
S-CVAE 1.31x / 1.11x at cpu / paper width, interaction 1.10x).  glibc alone cannot be tuned out of it: its trim /
mmap settings leave the faults, and a single arena (``MALLOC_ARENA_MAX=1``) removes them but serialises XLA's
threads on one lock, which costs as much as it saves or more.

:func:`reexec` restarts the running command once with the first library of :data:`LIBRARIES` present in
:data:`LIBRARY_DIRS` in ``LD_PRELOAD``; the ``inbetween`` console script calls it first.  Nothing changes (and nothing is
restarted) when none is installed, when ``LD_PRELOAD`` is already set, or when ``INBETWEEN_MALLOC=system`` asks
for the C library's own ``malloc``.  The numbers computed are the same with either; only the time differs.
Child processes (multi-process training's workers) inherit the preload through the environment.
"""
from __future__ import annotations

import os
import sys

__all__ = ["LIBRARIES", "LIBRARY_DIRS", "OPT_OUT_ENV", "MARK_ENV", "elf_kind", "find", "preload_env",
           "reexec"]

# (shared library, environment it needs): tcmalloc first (no settings needed); jemalloc's default 10 s decay
# returns pages between the seconds-long steps of the larger models, so it is switched off.
LIBRARIES = (("libtcmalloc_minimal.so.4", {}),
             ("libjemalloc.so.2", {"MALLOC_CONF": "dirty_decay_ms:-1,muzzy_decay_ms:-1"}))
LIBRARY_DIRS = ("/usr/lib/x86_64-linux-gnu", "/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu",
                "/lib/aarch64-linux-gnu", "/usr/lib64", "/usr/lib", "/usr/local/lib")   # Debian / Ubuntu / Fedora
OPT_OUT_ENV = "INBETWEEN_MALLOC"          # "system": keep the C library's malloc
MARK_ENV = "INBETWEEN_MALLOC_PRELOADED"   # set in the restarted process: never restart twice


def elf_kind(path: str):
    """``(class, byte order, machine)`` from an ELF file's header (bytes 4, 5 and 18-19), or None for a file that
    cannot be read or is not ELF."""
    try:
        with open(path, "rb") as f:
            head = f.read(20)
    except OSError:
        return None
    if len(head) < 20 or head[:4] != b"\x7fELF":
        return None
    return head[4], head[5], head[18:20]


def find(libraries=LIBRARIES, dirs=LIBRARY_DIRS, kind=None):
    """``(path, environment)`` of the first library present in ``dirs`` (Linux only) that the running interpreter
    can load, else None.  ``kind``: the :func:`elf_kind` a library must have (default: the interpreter's own), so
    a 32-bit or other-architecture copy (Fedora's ``/usr/lib``, a multi-arch folder) is passed over instead of
    making the loader print a warning in every process.  File reads only, no subprocess: every ``inbetween``
    command pays it at start."""
    if not sys.platform.startswith("linux"):
        return None
    kind = elf_kind(sys.executable) if kind is None else kind
    if kind is None:
        return None
    for name, env in libraries:
        for d in dirs:
            path = os.path.join(d, name)
            if os.path.isfile(path) and elf_kind(path) == kind:
                return path, dict(env)
    return None


def preload_env(environ=None, found=None) -> dict | None:
    """The environment to restart the command with (``LD_PRELOAD`` and the library's settings added to
    ``environ``, default ``os.environ``), or None to run on as it is.  ``found``: :func:`find`'s answer (looked up
    when None; ``()`` for none installed).  A setting the user already made (``MALLOC_CONF``) is kept."""
    env = dict(os.environ if environ is None else environ)
    if env.get(OPT_OUT_ENV) == "system" or env.get(MARK_ENV) or env.get("LD_PRELOAD"):
        return None
    found = find() if found is None else found
    if not found:
        return None
    path, extra = found
    return {**env, **{k: v for k, v in extra.items() if k not in env}, "LD_PRELOAD": path, MARK_ENV: path}


def reexec() -> None:
    """Restart this process (the same interpreter and command line, ``sys.orig_argv``) under
    :func:`preload_env`'s environment; returns (and changes nothing) when there is nothing to restart with or the
    restart fails.  Call it first thing, before any thread or output exists."""
    env = preload_env()
    if env is None:
        return
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        os.execve(sys.executable, list(sys.orig_argv), env)
    except OSError:
        return
