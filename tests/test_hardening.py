"""Hostile and malformed inputs to the ``inbetween`` command and the training dispatcher.

Every case must end with exit status 2, exactly one stderr line ``inbetween: error: ...`` holding the
expected phrase (and the offending file's name where there is one), no traceback, and nothing in ``--out``.
Malformed BVH files are made in ``tmp_path`` from a real shipped clip.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from inbetween_jax.cli import main
from inbetween_jax.data import read_bvh, write_bvh
from inbetween_jax.data.skeleton import Skeleton

ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "inbetween_jax", "assets", "cmu30")
CLIP_A, CLIP_B = os.path.join(ASSETS, "02_01.bvh"), os.path.join(ASSETS, "02_02.bvh")   # 86 and 76 frames

SRC_TEXT = open(CLIP_A).read()
HEADER, BODY = SRC_TEXT.split("MOTION\n", 1)
ROWS = BODY.splitlines()[2:]                       # frame lines after "Frames:" and "Frame Time:"


@pytest.fixture(scope="module")
def runs(cli_runs):
    return cli_runs


# ----------------------------------------------------------------------------- malformed BVH makers
def _motion_text(rows, frames=None, frame_time="0.033333"):
    return HEADER + f"MOTION\nFrames: {len(rows) if frames is None else frames}\nFrame Time: {frame_time}\n" + \
        "\n".join(rows) + "\n"


def _replace_value(row: int, col: int, value: str) -> str:
    rows = list(ROWS)
    words = rows[row].split()
    words[col] = value
    rows[row] = " ".join(words)
    return _motion_text(rows)


def _fewer_joints(path) -> None:
    """The clip without its last (leaf) joint: a 20-joint skeleton."""
    m = read_bvh(CLIP_A)
    s = m.skeleton
    last = s.num_joints - 1
    assert last not in s.parents                                      # a leaf
    sk = Skeleton(s.names[:-1], s.parents[:-1], s.offsets[:-1], s.channels[:-1],
                  tuple(e for e in s.end_sites if e[0] != last) + ((s.parents[last], s.offsets[last]),))
    m2 = type(m)(sk, m.local_quats[:, :-1], m.local_pos[:, :-1], m.frame_time)
    write_bvh(path, m2)


BAD_BVH = {   # name: (file text or a writer function, expected phrase)
    "truncated_motion": (SRC_TEXT[:len(SRC_TEXT) // 2].rsplit("\n", 1)[0] + "\n", "truncated MOTION block"),
    "truncated_hierarchy": (HEADER[:len(HEADER) // 2].rsplit("\n", 1)[0] + "\n", "file ends before the MOTION"),
    "cut_in_channels_line": (HEADER[:HEADER.index("Xrotation", 400)], "CHANNELS says 3 but lists"),
    "truncated_mid_line": (SRC_TEXT[:len(SRC_TEXT) - 40], "values, the hierarchy declares"),
    "nan_value": (_replace_value(3, 4, "nan"), "non-finite value 'nan'"),
    "inf_value": (_replace_value(7, 10, "inf"), "non-finite value 'inf'"),
    "overflow_value": (_replace_value(2, 0, "1e999"), "non-finite value '1e999'"),
    "non_numeric_value": (_replace_value(1, 5, "12,5"), "non-numeric value '12,5'"),
    "empty_file": ("", "missing HIERARCHY header"),
    "binary_garbage": (bytes(range(256)) * 8, "not a text file"),
    "huge_frame_count": (_motion_text(ROWS[:2], frames=100000000), "header says 100000000 frames, found 2"),
    "nan_frame_count": (_motion_text(ROWS[:2], frames="nan"), "Frames must be a positive integer"),
    "negative_frame_time": (_motion_text(ROWS, frame_time="-0.033333"), "Frame Time must be positive"),
    "duplicate_joint": (SRC_TEXT.replace("JOINT lShldr", "JOINT rShldr", 1), "'rShldr' appears more than once"),
    "renamed_joint": (SRC_TEXT.replace("JOINT head", "JOINT Head", 1), "'Head' but the checkpoint expects 'head'"),
    "fewer_joints": (_fewer_joints, "skeleton has 20 joints but the checkpoint was trained on 21"),
}


def _write_bad(tmp_path, name) -> str:
    content, _ = BAD_BVH[name]
    path = tmp_path / f"bad_{name}.bvh"
    if callable(content):
        content(path)
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return str(path)


def _scvae(runs, start=CLIP_A, end=CLIP_B, frames=8, samples=2, ckpt=None):
    return ["--model", "scvae", "--ckpt", ckpt or runs["scvae"], "--start", start, "--end", end,
            "--frames", str(frames), "--samples", str(samples)]


def _cae(runs, gaps="10:20", bvh=CLIP_A):
    return ["--model", "cae", "--ckpt", runs["cae"], "--bvh", bvh, "--gaps", gaps]


def _inter(runs, a=f"{CLIP_A}:30", frames=10):
    return ["--model", "interaction", "--ckpt", runs["interaction"], "--a", a, "--b", f"{CLIP_B}:30",
            "--key-a", f"{CLIP_A}:60", "--key-b", f"{CLIP_B}:60", "--frames", str(frames)]


# name: (argv maker (runs, tmp_path) -> (args, file name in the message or None), expected phrase)
CASES = {
    "missing_file": (lambda r, t: (_scvae(r, start=str(t / "nope.bvh")), "nope.bvh"), "file not found"),
    "directory_as_file": (lambda r, t: (_scvae(r, end=str(t)), t.name), "is a directory"),
    "frame_not_integer": (lambda r, t: (_scvae(r, start=f"{CLIP_A}:abc"), "02_01.bvh"), "'abc' is not an integer"),
    "frame_negative": (lambda r, t: (_scvae(r, end=f"{CLIP_B}:-5"), "02_02.bvh"), "frame -5 is out of range"),
    "frame_too_large": (lambda r, t: (_scvae(r, start=f"{CLIP_A}:999999"), "02_01.bvh"), "has 86 frames"),
    "frames_zero": (lambda r, t: (_scvae(r, frames=0), None), "--frames must be a positive"),
    "frames_one": (lambda r, t: (_scvae(r, frames=1), None), "generates 3..10 frames"),
    "frames_1000": (lambda r, t: (_scvae(r, frames=1000), None), "generates 3..10 frames"),
    "frames_not_a_number": (lambda r, t: (_scvae(r, frames="ten"), None), "invalid int value: 'ten'"),
    "samples_zero": (lambda r, t: (_scvae(r, samples=0), None), "--samples must be between 1"),
    "samples_negative": (lambda r, t: (_scvae(r, samples=-3), None), "--samples must be between 1"),
    "unknown_model": (lambda r, t: (["--model", "gan", "--ckpt", r["scvae"]], None), "unknown model 'gan'"),
    "missing_ckpt_folder": (lambda r, t: (_scvae(r, ckpt=str(t / "no_run")), "no_run"), "does not exist"),
    "ckpt_without_checkpoints": (lambda r, t: (_scvae(r, ckpt=str(_mkdir(t / "empty_run"))), "empty_run"),
                                 "not a run folder (no run.json)"),
    "ckpt_of_other_model": (lambda r, t: (_scvae(r, ckpt=r["interaction"]), "interaction"),
                            "holds a run of model 'interaction', not 'scvae'"),
    "option_of_other_model": (lambda r, t: (_scvae(r) + ["--gaps", "1:2"], None), "--gaps is not used"),
    "gaps_reversed": (lambda r, t: (_cae(r, "10:5"), None), "gap 10:5 must have 0 <= START < STOP"),
    "gaps_not_numbers": (lambda r, t: (_cae(r, "a:b"), None), "'a:b' is not START:STOP"),
    "gaps_beyond_length": (lambda r, t: (_cae(r, "50:500"), "02_01.bvh"), "beyond the end"),
    "gaps_cover_all": (lambda r, t: (_cae(r, "0:86"), "02_01.bvh"), "cover all 86 frames"),
    "interaction_short_context": (lambda r, t: (_inter(r, a=f"{CLIP_A}:5"), "02_01.bvh"), "frames of context"),
    "interaction_frames_1000": (lambda r, t: (_inter(r, frames=1000), None), "at most 60 frames"),
    "out_is_a_file": (lambda r, t: (_scvae(r), None), "exists and is not a folder"),
    "end_on_another_rig": (lambda r, t: (_scvae(r, end=_written(t / "rig20.bvh", _fewer_joints)), "rig20.bvh"),
                           "has 20 joints where the other keyframe's file has 21 ("),
    "end_with_renamed_joint": (lambda r, t: (_scvae(r, end=_written(t / "renamed.bvh", _renamed_head)), "renamed.bvh"),
                               "where the other keyframe's file has 'head'"),
}


def _renamed_head(path) -> None:
    path.write_text(SRC_TEXT.replace("JOINT head", "JOINT Head", 1))


def _written(path, writer) -> str:
    writer(path)
    return str(path)


def _mkdir(path):
    path.mkdir(exist_ok=True)
    return path


def _expect_one_error(capsys, phrase, filename=None) -> str:
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("inbetween: error: ") and phrase in line, line
    if filename:
        assert filename in line, line
    assert "Traceback" not in err + out
    return line


def _assert_nothing_written(out) -> None:
    assert not out.exists() or (out.is_dir() and not any(out.iterdir()))
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}.tmp")]


@pytest.mark.parametrize("name", sorted(BAD_BVH))
def test_malformed_bvh(name, runs, tmp_path, capsys):
    path = _write_bad(tmp_path, name)
    out = tmp_path / "out"
    assert main(["infill"] + _scvae(runs, start=path) + ["--out", str(out)]) == 2
    _expect_one_error(capsys, BAD_BVH[name][1], os.path.basename(path))
    _assert_nothing_written(out)


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_arguments(name, runs, tmp_path, capsys):
    make, phrase = CASES[name]
    args, filename = make(runs, tmp_path)
    out = tmp_path / "out"
    if name == "out_is_a_file":
        out.write_text("keep me")
    assert main(["infill"] + args + ["--out", str(out)]) == 2
    _expect_one_error(capsys, phrase, filename)
    if name == "out_is_a_file":
        assert out.read_text() == "keep me"
    else:
        _assert_nothing_written(out)


def test_cae_rejects_malformed_bvh_and_other_skeleton(runs, tmp_path, capsys):
    for name in ("inf_value", "renamed_joint"):
        path = _write_bad(tmp_path, name)
        assert main(["infill"] + _cae(runs, bvh=path) + ["--out", str(tmp_path / "out")]) == 2
        _expect_one_error(capsys, BAD_BVH[name][1], os.path.basename(path))
    _assert_nothing_written(tmp_path / "out")


def test_non_empty_out_is_left_alone(runs, tmp_path, capsys):
    out = _mkdir(tmp_path / "out")
    (out / "mine.txt").write_text("x")
    assert main(["infill"] + _scvae(runs) + ["--out", str(out)]) == 2
    _expect_one_error(capsys, "folder is not empty")
    assert sorted(os.listdir(out)) == ["mine.txt"]


def test_python_api_rejects_non_unit_quaternions(runs):
    """``infill_between`` checks the keyframes it is given before touching the model."""
    from inbetween_jax.data.user_input import check_unit_quats
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.train.run import load_run
    trained = infer.Trained(infer.load(load_run(runs["scvae"])).cfg, None, 0, None, {})
    m = read_bvh(CLIP_A)
    good = {"q": m.local_quats[0], "r": m.root_pos[0], "c": np.zeros(4)}
    bad = dict(good, q=m.local_quats[0] * np.where(np.arange(21) == 4, 1.7, 1.0)[:, None])
    with pytest.raises(ValueError, match=r"start keyframe q: quaternion \(4,\) has norm 1\.7"):
        infer.infill_between(trained, m.skeleton, bad, good, 8, 1)
    with pytest.raises(ValueError, match="end keyframe q: quaternions hold NaN"):
        infer.infill_between(trained, m.skeleton, good, dict(good, q=good["q"] * np.nan), 8, 1)
    with pytest.raises(ValueError, match="keys: expected quaternions of shape"):
        check_unit_quats(np.ones((3, 3)), "keys")


def test_training_divergence_is_one_line_with_its_step(tmp_path, capsys):
    """``inbetween train`` reports a NaN loss with its step in one line (exit status 2)."""
    rc = main(["train", "cae", "--source", "embedded", "--preset", "tiny", "--run-dir", str(tmp_path / "run"),
               "--no-progress", "train.lr=1e30", "train.num_steps=2", "train.log_every=1", "train.ckpt_every=2"])
    out, err = capsys.readouterr()
    assert rc == 2
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.startswith("inbetween: error:")]
    assert len(lines) == 1 and "non-finite loss" in lines[0] and "at step 2" in lines[0], err
    assert "Traceback" not in err + out
    assert not os.listdir(tmp_path / "run" / "checkpoints")                   # no diverged state saved
    assert main(["train", "gan"]) == 2
    assert capsys.readouterr().err.strip() == "inbetween: error: unknown model 'gan' (choose scvae, cae, interaction)"


TRAIN_ERRORS = {   # argv after "train": expected phrase
    "bad_key": (["cae", "model.chanels=4"], "unknown config key 'model.chanels' (did you mean 'channels'?)"),
    "bad_value": (["cae", "train.num_steps=ten"], "expected int, got 'ten'"),
    "not_key_value": (["cae", "num_steps"], "is not of the form key=value"),
    "bad_preset": (["scvae", "--preset", "huge"], "unknown preset 'huge' for scvae"),
    "missing_source": (["interaction", "--source", "/nonexistent/folder"], "no such folder"),
    "bad_processes": (["cae", "--num-processes", "0"], "--num-processes must be >= 1"),
}


@pytest.mark.parametrize("name", sorted(TRAIN_ERRORS))
def test_train_argument_errors(name, tmp_path, capsys):
    argv, phrase = TRAIN_ERRORS[name]
    assert main(["train"] + argv + ["--run-dir", str(tmp_path / "run")]) == 2
    _expect_one_error(capsys, phrase)
    assert not (tmp_path / "run").exists()


def test_overlapping_gaps_are_merged_and_said(runs, tmp_path, capsys):
    """``--gaps 20:40,30:50`` fills 20:50 once and says so in one note line."""
    out = tmp_path / "out"
    assert main(["infill"] + _cae(runs, gaps="20:40,30:50") + ["--out", str(out)]) == 0
    _, err = capsys.readouterr()
    assert "inbetween: note: --gaps 20:40,30:50: overlapping gaps merged into 20:50" in err
    import json
    assert json.loads((out / "infill.json").read_text())["gaps"] == [[20, 50]]


DAMAGED = {   # how a run folder is damaged: expected phrase
    "empty_step_folder": "no checkpoint found",
    "zero_byte_files": "",
    "empty_run_json": "run.json is unreadable",
    "no_run_json": "not a run folder",
}


@pytest.mark.parametrize("damage", sorted(DAMAGED))
def test_damaged_run_folder_is_one_line(damage, runs, tmp_path, capfd):
    """A damaged run folder gives one line naming the folder, with no logging noise on stderr."""
    import shutil
    run = tmp_path / "run"
    shutil.copytree(runs["cae"], run)
    steps = sorted(int(d) for d in os.listdir(run / "checkpoints") if d.isdigit())
    if damage == "empty_step_folder":
        for s in steps:
            shutil.rmtree(run / "checkpoints" / str(s))
            (run / "checkpoints" / str(s)).mkdir()
    elif damage == "zero_byte_files":
        for dirpath, _, files in os.walk(run / "checkpoints"):
            for f in files:
                open(os.path.join(dirpath, f), "w").close()
    elif damage == "empty_run_json":
        (run / "run.json").write_text("")
    else:
        (run / "run.json").unlink()
    out = tmp_path / "out"
    assert main(["infill", "--model", "cae", "--ckpt", str(run), "--bvh", CLIP_A, "--gaps", "10:20",
                 "--out", str(out)]) == 2
    _, err = capfd.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inbetween: error: ") and "run" in lines[0], err
    assert DAMAGED[damage] in lines[0], lines[0]
    _assert_nothing_written(out)


def test_bench_l2p_stats_file_is_read_or_refused_in_one_line(tmp_path):
    """``inbetween bench --l2p-stats FILE``: the official statistics' two arrays are read as they are; a file
    without them, or not an .npz at all, is one line naming it."""
    from inbetween_jax.cli.bench_cmd import load_l2p_stats
    from inbetween_jax.errors import UserError
    good, partial, junk = (str(tmp_path / n) for n in ("stats.npz", "partial.npz", "junk.npz"))
    np.savez(good, x_mean=np.arange(6.0).reshape(1, 6, 1), x_std=np.full((1, 6, 1), 2.0))
    np.savez(partial, x_mean=np.zeros((1, 6, 1)))
    open(junk, "wb").write(b"PK\x03\x04 cut short")
    x_mean, x_std, note = load_l2p_stats("embedded", good)
    assert x_mean.shape == (1, 6, 1) and x_mean[0, 5, 0] == 5.0 and x_std.max() == 2.0 and "stats.npz" in note
    for path in (partial, junk):
        with pytest.raises(UserError) as e:
            load_l2p_stats("embedded", path)
        assert path in str(e.value) and "\n" not in str(e.value)
