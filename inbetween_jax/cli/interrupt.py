"""Prompt, clean Ctrl-C for the command line.

Python runs a SIGINT handler only between bytecodes, so an interrupt that arrives during a long XLA compile or
a matplotlib render waits until that call returns (over a minute has been seen).  Instead, SIGINT is blocked in
every thread and a watcher thread waits for it with ``sigwait``: it wakes up as soon as the signal arrives (the
long calls release the GIL), removes the temporary folders made with :func:`temp_dir`, prints one line and
ends the process with status 130.  The main thread keeps running meanwhile, so each folder is first
renamed aside (no new file can land in it) and then removed, and the main thread's own error lines
(:func:`say`) wait for the exit instead of following the interrupt's line.  Child processes registered with
:func:`track_process` (``train --num-processes N``) get the SIGINT too and are killed if they have not ended
within :data:`CHILD_GRACE_S`, so none outlives the command when only it was signalled.  Outputs are only
moved into place inside :func:`critical` sections, which an interrupt lets finish first, so nothing is left
half-written.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

__all__ = ["install", "temp_dir", "track", "untrack", "track_process", "critical", "say"]

CHILD_GRACE_S = 5.0
_lock = threading.RLock()
_temp: set[str] = set()
_children: list = []
_state = {"installed": False, "pending": False, "depth": 0, "message": "interrupted"}


def _remove(path: str) -> None:
    doomed = f"{path}.removing"
    try:
        os.rename(path, doomed)          # the main thread's next write into ``path`` fails instead of landing
    except OSError:
        doomed = path
    shutil.rmtree(doomed, ignore_errors=True)


def _stop_children() -> None:
    alive = [p for p in _children if p.poll() is None]
    for p in alive:
        p.send_signal(signal.SIGINT)
    deadline = time.monotonic() + CHILD_GRACE_S
    for p in alive:
        try:
            p.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _exit_now() -> None:
    """Called with ``_lock`` held, which it never releases: :func:`say` in other threads waits for the exit."""
    _stop_children()
    for path in list(_temp):
        _remove(path)
    try:
        if _state["message"] is not None:
            sys.stderr.write(f"inbetween: {_state['message']}\n")
            sys.stderr.flush()
    finally:
        os._exit(130)


def _watch() -> None:
    while True:
        signal.sigwait({signal.SIGINT})
        with _lock:
            if _state["depth"] > 0:
                _state["pending"] = True
                continue
            _exit_now()


QUIET_ENV = "INBETWEEN_QUIET_INTERRUPT"      # set by the local launcher for its children: it prints the line


def install(message: str | None = "interrupted") -> None:
    """Route Ctrl-C to the watcher thread (main thread only; a no-op elsewhere or when already installed).
    ``message`` None: exit with status 130 and print nothing (a child whose launcher prints the line)."""
    _state["message"] = message
    if _state["installed"] or threading.current_thread() is not threading.main_thread():
        return
    if not hasattr(signal, "pthread_sigmask"):
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    threading.Thread(target=_watch, name="inbetween-sigint", daemon=True).start()
    _state["installed"] = True


def temp_dir(prefix: str, parent: str) -> str:
    """A new temporary folder in ``parent``, removed if the process is interrupted; made and registered under
    the lock, so an interrupt cannot fall between the two."""
    with _lock:
        path = tempfile.mkdtemp(prefix=prefix, dir=parent)
        _temp.add(path)
    return path


def say(line: str) -> None:
    """Print one line to stderr, unless an interrupt is ending the process (then wait for that exit)."""
    with _lock:
        print(line, file=sys.stderr)


def track(path: str) -> None:
    """Remove ``path`` (a temporary folder) if the process is interrupted."""
    with _lock:
        _temp.add(path)


def untrack(path: str) -> None:
    with _lock:
        _temp.discard(path)


def track_process(proc) -> None:
    """Stop ``proc`` (a :class:`subprocess.Popen`) if this process is interrupted: SIGINT, then SIGKILL after
    :data:`CHILD_GRACE_S` seconds."""
    with _lock:
        _children.append(proc)


@contextlib.contextmanager
def critical():
    """A section an interrupt lets finish (moving finished outputs into place); the exit follows it."""
    with _lock:
        _state["depth"] += 1
    try:
        yield
    finally:
        with _lock:
            _state["depth"] -= 1
            if _state["depth"] == 0 and _state["pending"]:
                _exit_now()
