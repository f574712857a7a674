"""Prompt, clean Ctrl-C for the command line.

Python runs a SIGINT handler only between bytecodes, so an interrupt that arrives during a long XLA compile or
a matplotlib render waits until that call returns (over a minute has been seen).  Instead, SIGINT is blocked in
every thread and a watcher thread waits for it with ``sigwait``: it wakes up as soon as the signal arrives (the
long calls release the GIL), removes the temporary folders made with :func:`temp_dir`, prints one line and
ends the process with status 130.  The main thread keeps running meanwhile, so each folder is first
renamed aside (no new file can land in it) and then removed, and the main thread's own error lines
(:func:`say`) wait for the exit instead of following the interrupt's line.  Functions registered with
:func:`at_exit` run before the line (``train --num-processes N`` stops its child processes there, so none
outlives the command when only it was signalled).  Outputs are only moved into place inside :func:`critical`
sections, which an interrupt lets finish first, so nothing is left half-written.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import signal
import sys
import tempfile
import threading

__all__ = ["install", "temp_dir", "track", "untrack", "at_exit", "critical", "say", "settle"]

_lock = threading.RLock()
_temp: set[str] = set()
_at_exit: list = []
_state = {"installed": False, "pending": False, "depth": 0, "message": "interrupted"}


def _remove(path: str) -> None:
    doomed = f"{path}.removing"
    try:
        os.rename(path, doomed)          # the main thread's next write into ``path`` fails instead of landing
    except OSError:
        doomed = path
    shutil.rmtree(doomed, ignore_errors=True)


def _exit_now() -> None:
    """Called with ``_lock`` held, which it never releases: :func:`say` in other threads waits for the exit."""
    try:
        for path in list(_temp):
            _remove(path)
        for fn in list(_at_exit):
            fn()
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


QUIET_ENV = "INBETWEEN_QUIET_INTERRUPT"      # set by ``train --num-processes`` for its children: it prints the line


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


def settle() -> None:
    """Before the main thread ends the process: wait for an interrupt that is already ending it (its clean-up
    and line come first; with ``--num-processes`` a child's exit can end the launcher's main loop meanwhile)."""
    with _lock:
        pass


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


def at_exit(fn) -> None:
    """Call ``fn()`` before an interrupt ends the process (``launch_local`` stops its children there)."""
    with _lock:
        _at_exit.append(fn)


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
