"""Ctrl-C on the console script: prompt exit with one line and status 130, nothing half-written.

The command runs in a child process (``python -m inbetween_jax.cli``, the console script's entry point) and gets
SIGINT while it is busy (reading / compiling / drawing); it must end within a few seconds of the signal.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from inbetween_jax.data import read_bvh, write_bvh

GIF_DONE = "preview: drew 401 frames"       # the preview's last piece of work: its GIF
ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "inbetween_jax", "assets", "cmu30")


def _interrupt(argv, cwd, after_s: float, after_line: str = "", env=None, done_line: str | None = None):
    """Run the CLI (with ``env`` added to the environment), send SIGINT ``after_s`` seconds after it printed a
    stderr line starting with ``after_line`` (after start when empty), and return (returncode, seconds from
    signal to exit, stdout, stderr).  Skips the test when the command finished first: it exited before the
    signal, or succeeded after printing ``done_line`` (its last piece of work was done before the signal)."""
    proc = subprocess.Popen([sys.executable, "-m", "inbetween_jax.cli", *map(str, argv)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, **(env or {})))
    lines, seen = [], threading.Event()

    def read_stderr():
        for line in proc.stderr:
            lines.append(line)
            if line.startswith(after_line):
                seen.set()
    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    if not after_line:
        seen.set()
    while not seen.wait(0.05) and proc.poll() is None:
        pass
    time.sleep(after_s)
    if proc.poll() is not None:   # too fast to interrupt on this machine: it must at least have succeeded
        proc.wait()
        reader.join(10)
        assert proc.returncode == 0, "".join(lines)
        pytest.skip("the command finished before the interrupt")
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out = proc.stdout.read()
    proc.wait(timeout=60)
    waited = time.monotonic() - sent
    reader.join(10)
    err = "".join(lines)
    if proc.returncode == 0 and done_line is not None and done_line in err:
        pytest.skip("the command finished its work before the signal arrived")
    return proc.returncode, waited, out, err


def _long_clip(path, frames: int = 6000) -> None:
    m = read_bvh(os.path.join(ASSETS, "02_01.bvh"))
    idx = np.concatenate([np.arange(m.num_frames), np.arange(m.num_frames)[::-1]])
    idx = np.resize(idx, frames)
    write_bvh(path, type(m)(m.skeleton, m.local_quats[idx], m.local_pos[idx], m.frame_time))


@pytest.mark.parametrize("kind", ["preview", "train"])
def test_ctrl_c_exits_promptly_with_one_line(kind, tmp_path):
    if kind == "preview":
        _long_clip(tmp_path / "long.bvh")
        argv = ["preview", tmp_path / "long.bvh", "--gif", "--out", tmp_path / "out"]
    else:
        argv = ["train", "cae", "--preset", "tiny", "--source", "embedded", "--run-dir", tmp_path / "out",
                "--no-progress", "train.num_steps=100000"]
    # preview draws its sheet, says so, then draws the GIF's 401 frames (seconds on 2 cores): it is interrupted
    # as soon as it says the sheet is drawn, so the signal lands in the GIF
    rc, waited, out, err = _interrupt(argv, tmp_path, after_s=0.0 if kind == "preview" else 6.0,
                                      after_line="preview: drew" if kind == "preview" else "",
                                      done_line=GIF_DONE if kind == "preview" else None)   # ~1.5 s to spare here
    assert rc == 130, err
    assert waited < 10.0, f"exit took {waited:.1f} s after Ctrl-C"
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()]
    assert lines[-1] == "inbetween: interrupted" and "Traceback" not in err, err
    leftovers = [p for p in os.listdir(tmp_path) if p.startswith(".")]
    assert not leftovers, leftovers                                   # no temporary folder left behind
    if kind == "preview":
        out_dir = tmp_path / "out"
        assert not out_dir.exists() or not [f for f in os.listdir(out_dir) if f.endswith((".png", ".gif"))]
        assert "drew 41 frames" in err and "drew 401" not in err        # stopped inside the GIF


def test_interrupt_removes_a_temp_folder_still_being_written(tmp_path):
    """The watcher removes a temporary folder while the main thread may still be writing files into it: the
    folder must be gone afterwards, and the writer's next file must fail rather than recreate it."""
    from inbetween_jax.cli import interrupt
    path = interrupt.temp_dir(".out.tmp-", str(tmp_path))
    assert os.path.isdir(path) and path in interrupt._temp
    stop, failed = threading.Event(), []

    def writer():
        i = 0
        while not stop.is_set():
            try:
                with open(os.path.join(path, f"f{i}.bin"), "wb") as f:
                    f.write(b"x" * 4096)
            except OSError:
                failed.append(i)
                return
            i += 1

    t = threading.Thread(target=writer)
    t.start()
    time.sleep(0.05)
    interrupt._remove(path)
    time.sleep(0.05)
    stop.set()
    t.join()
    interrupt.untrack(path)
    assert failed, "the writer never noticed the folder was gone"
    assert os.listdir(tmp_path) == []


def test_a_launched_child_exits_130_without_a_line(tmp_path):
    """A child of the local launcher (``train --num-processes N`` gives its children ``QUIET_ENV``) ends with
    130 on Ctrl-C and prints no line of its own, so the terminal shows the launcher's one line only."""
    from inbetween_jax.cli.interrupt import QUIET_ENV
    _long_clip(tmp_path / "long.bvh")
    rc, waited, out, err = _interrupt(["preview", tmp_path / "long.bvh", "--gif", "--out", tmp_path / "out"],
                                      tmp_path, after_s=0.0, after_line="preview: drew", env={QUIET_ENV: "1"},
                                      done_line=GIF_DONE)
    assert rc == 130 and waited < 10.0, err
    assert "interrupted" not in err and "Traceback" not in err, err
