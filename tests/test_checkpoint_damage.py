"""Damaged checkpoints give one-line ``CheckpointError`` messages naming the folder, and nothing else on stderr.

A real checkpoint (joint rotations of an embedded CMU clip, a typed PRNG key and a step counter) is
written once, copied per case and damaged the way an interrupted copy / full disk / hand edit would.
"""
from __future__ import annotations

import glob
import os
import shutil
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.data import load_dataset
from inbetween_jax.train import Checkpointer, CheckpointError, run_training

STEP = 5


def _state():
    quats = jnp.asarray(load_dataset("embedded", "train").local_quats[0, 0])          # (J, 4) real rotations
    return {"quats": quats, "key": jax.random.key(3), "step": jnp.int32(STEP)}


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    folder = str(tmp_path_factory.mktemp("ckpt_template") / "checkpoints")
    with Checkpointer(folder) as ck:
        ck.save(STEP, _state(), {"seed": 0, "step": STEP}, force=True)
    return folder


@pytest.fixture
def ckdir(template, tmp_path):
    folder = str(tmp_path / "run" / "checkpoints")
    shutil.copytree(template, folder)
    return folder


def _target():
    return jax.eval_shape(_state)


def _truncate(pattern):
    files = [f for f in glob.glob(pattern, recursive=True) if os.path.isfile(f)]
    assert files, pattern
    for f in files:
        open(f, "w").close()


def _assert_one_error(capfd, call, folder, *fragments):
    capfd.readouterr()
    with pytest.raises(CheckpointError) as info:
        call()
    msg = str(info.value)
    assert isinstance(info.value, ValueError)
    assert "\n" not in msg and msg.startswith(folder + ":"), msg
    for frag in fragments:
        assert frag in msg, msg
    cap = capfd.readouterr()
    assert cap.err == "" and cap.out == "", cap.err         # no absl / orbax / asyncio noise


def test_intact_checkpoint_restores(ckdir, capfd):
    with Checkpointer(ckdir) as ck:
        state, extra = ck.restore(None, _target()), ck.restore_extra(STEP)
    np.testing.assert_array_equal(np.asarray(state["quats"]), np.asarray(_state()["quats"]))
    assert extra == {"seed": 0, "step": STEP} and int(state["step"]) == STEP
    assert capfd.readouterr().err == ""


def test_empty_step_folder(ckdir, capfd):
    os.makedirs(os.path.join(ckdir, "7"))                   # newer than the good step 5: it is the latest
    with Checkpointer(ckdir) as ck:
        _assert_one_error(capfd, lambda: ck.restore(None, _target()), os.path.join(ckdir, "7"),
                          "empty checkpoint folder")
        _assert_one_error(capfd, lambda: ck.restore_extra(7), os.path.join(ckdir, "7"), "empty checkpoint folder")


def test_resuming_a_run_with_an_empty_step_folder(ckdir, capfd):
    os.makedirs(os.path.join(ckdir, "7"))
    run_dir = os.path.dirname(ckdir)
    _assert_one_error(capfd, lambda: run_training(_state, lambda s, b, k: (s, {}), lambda i, k: {}, {}, run_dir, 9,
                                                  progress=False, compilation_cache=False),
                      os.path.join(ckdir, "7"), "empty checkpoint folder")
    assert not os.path.exists(os.path.join(run_dir, "metrics.csv"))      # nothing written


def test_zero_byte_files(ckdir, capfd):
    _truncate(os.path.join(ckdir, str(STEP), "state", "**", "d", "*"))
    with Checkpointer(ckdir) as ck:
        _assert_one_error(capfd, lambda: ck.restore(STEP, _target()), os.path.join(ckdir, str(STEP)),
                          "is empty (0 bytes)", "state/")


def test_corrupt_array_data(ckdir):
    """Garbage array bytes are only found by orbax itself: its error becomes one CheckpointError line.  (The
    late reports of reads still in flight are checked in a fresh process, below.)"""
    files = glob.glob(os.path.join(ckdir, str(STEP), "state", "**", "d", "*"), recursive=True)
    assert files
    for f in files:
        with open(f, "wb") as fh:
            fh.write(b"\x00garbage" * 8)
    with Checkpointer(ckdir) as ck, pytest.raises(CheckpointError) as info:
        ck.restore(STEP, _target())
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(os.path.join(ckdir, str(STEP)) + ": cannot restore 'state'"), msg


def test_missing_step_metadata(ckdir, capfd):
    os.remove(os.path.join(ckdir, str(STEP), "_CHECKPOINT_METADATA"))
    with Checkpointer(ckdir) as ck:
        _assert_one_error(capfd, lambda: ck.restore(STEP, _target()), os.path.join(ckdir, str(STEP)),
                          "missing metadata file _CHECKPOINT_METADATA")


@pytest.mark.parametrize("rel", ["_CHECKPOINT_METADATA", os.path.join("state", "_METADATA"),
                                 os.path.join("extra", "metadata")])
def test_corrupt_metadata(ckdir, capfd, rel):
    with open(os.path.join(ckdir, str(STEP), rel), "w") as f:
        f.write('{"truncated": ')
    with Checkpointer(ckdir) as ck:
        extra = rel.startswith("extra")
        call = (lambda: ck.restore_extra(STEP)) if extra else (lambda: ck.restore(STEP, _target()))
        _assert_one_error(capfd, call, os.path.join(ckdir, str(STEP)), f"corrupt metadata file {rel}")


def test_folder_without_checkpoints(tmp_path, capfd):
    folder = str(tmp_path / "run" / "checkpoints")
    os.makedirs(folder)
    with Checkpointer(folder) as ck:
        assert ck.latest_step() is None
        _assert_one_error(capfd, lambda: ck.latest_step(required=True), folder, "no checkpoint found")
        _assert_one_error(capfd, lambda: ck.restore(None, _target()), folder, "no checkpoint found")


def test_unknown_step(ckdir, capfd):
    with Checkpointer(ckdir) as ck:
        _assert_one_error(capfd, lambda: ck.restore_extra(9), ckdir, "no checkpoint for step 9", "available: 5")


CHILD = r"""
import glob, os, shutil, sys
import jax, jax.numpy as jnp
from inbetween_jax.data import load_dataset
from inbetween_jax.train import Checkpointer, CheckpointError
root = sys.argv[1]
clip = load_dataset("embedded", "train")
state = {"quats": jnp.asarray(clip.local_quats[0, 0]), "root": jnp.asarray(clip.root_pos[0, 0]),
         "key": jax.random.key(3), "step": jnp.int32(5)}
with Checkpointer(f"{root}/good") as ck:
    ck.save(5, state, {"seed": 0}, force=True)
damage = {
    "empty": lambda d: os.makedirs(f"{d}/7"),
    "zero": lambda d: [open(f, "w").close() for f in glob.glob(f"{d}/5/state/**/d/*", recursive=True)],
    "missing": lambda d: os.remove(f"{d}/5/_CHECKPOINT_METADATA"),
    "corrupt": lambda d: open(f"{d}/5/state/_METADATA", "w").write("{"),
    "none": lambda d: shutil.rmtree(f"{d}/5"),
}
for i in range(3):   # reads in flight report late, on other threads, in most runs: give them three chances
    damage[f"garbage{i}"] = lambda d: [open(f, "wb").write(b"\x00garbage" * 8)
                                       for f in glob.glob(f"{d}/5/state/**/d/*", recursive=True)]
for name, hurt in damage.items():
    d = f"{root}/{name}"
    shutil.copytree(f"{root}/good", d)
    hurt(d)
    with Checkpointer(d) as ck:
        try:
            ck.restore(None, jax.eval_shape(lambda: state))
        except CheckpointError as e:
            print(name, "|", e)
"""


def test_damaged_checkpoints_leave_stderr_empty_in_a_fresh_process(tmp_path):
    """Same cases in a plain interpreter: pytest's log capture cannot hide absl / orbax lines there, and reads
    of garbage array data still in flight after the failed restore would print tracebacks on other threads."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    proc = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path)], cwd=root, capture_output=True,
                          text=True, timeout=300, env=dict(os.environ, JAX_PLATFORMS="cpu"))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr[-3000:]
    lines = dict(line.split(" | ", 1) for line in proc.stdout.splitlines())
    assert sorted(lines) == ["corrupt", "empty", "garbage0", "garbage1", "garbage2", "missing", "none", "zero"]
    for i in range(3):
        assert lines[f"garbage{i}"].startswith(f"{tmp_path}/garbage{i}/5: cannot restore 'state'")
    assert lines["empty"] == f"{tmp_path}/empty/7: empty checkpoint folder (an interrupted save? delete it to " \
                             "use an earlier checkpoint)"
    assert lines["zero"].startswith(f"{tmp_path}/zero/5: file state/")
    assert lines["zero"].endswith("is empty (0 bytes)")
    assert lines["missing"].startswith(f"{tmp_path}/missing/5: missing metadata file _CHECKPOINT_METADATA")
    assert lines["corrupt"].startswith(f"{tmp_path}/corrupt/5: corrupt metadata file state/_METADATA")
    assert lines["none"].startswith(f"{tmp_path}/none: no checkpoint found")
