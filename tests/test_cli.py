"""End-to-end tests of the ``inbetween`` console script on the shipped CMU BVH files, one tiny run per model.

Runs are made once per test session by the ``cli_runs`` fixture (``conftest.py``, shared with
``test_hardening.py``).  Every written BVH is read back with our reader and with the independent ``bvhio``
package.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from inbetween_jax.cli import main
from inbetween_jax.data import read_bvh
from inbetween_jax.geometry import forward_kinematics

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLIP_A = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30", "02_01.bvh")   # 86 frames
CLIP_B = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30", "02_02.bvh")   # 76 frames
SCVAE_FRAMES, INTER_FRAMES = 8, 12


@pytest.fixture(scope="module")
def runs(cli_runs):
    return cli_runs


def positions(motion) -> np.ndarray:
    return forward_kinematics(motion.local_quats, motion.local_pos, motion.skeleton.parents)[1]


def assert_same_skeleton(path, src) -> None:
    a, b = read_bvh(path).skeleton, read_bvh(src).skeleton
    assert a.names == b.names and a.parents == b.parents and a.channels == b.channels
    np.testing.assert_allclose(a.offsets, b.offsets, atol=1e-6)


def assert_bvhio_agrees(path, frames) -> None:
    """The independent ``bvhio`` reader sees the world joint positions of our FK (1e-3)."""
    bvhio = pytest.importorskip("bvhio")
    m = read_bvh(path)
    gp = positions(m)
    root = bvhio.readAsHierarchy(str(path))
    joints = [j for j, _, _ in root.layout() if j.Name in m.skeleton.names]
    assert len(joints) == m.skeleton.num_joints
    idx = [m.skeleton.index(j.Name) for j in joints]
    for f in frames:
        root.loadPose(f)
        theirs = np.array([list(j.PositionWorld) for j in joints])
        np.testing.assert_allclose(theirs, gp[f, idx], atol=1e-3)


def run_cli(argv, capsys):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert rc == 0, err
    return out


def test_scvae_infill(runs, tmp_path, capsys):
    out = tmp_path / "out"
    run_cli(["infill", "--model", "scvae", "--ckpt", runs["scvae"], "--start", f"{CLIP_A}:5", "--end", f"{CLIP_B}:40",
             "--frames", SCVAE_FRAMES, "--samples", 3, "--out", out, "--seed", 1], capsys)
    names = sorted(os.listdir(out))
    assert names == ["infill.json", "sample_00.bvh", "sample_01.bvh", "sample_02.bvh"]
    start, end = positions(read_bvh(CLIP_A))[5], positions(read_bvh(CLIP_B))[40]
    mids = []
    for n in names[1:]:
        m = read_bvh(out / n)
        assert m.num_frames == SCVAE_FRAMES + 2 and abs(m.frame_time - read_bvh(CLIP_A).frame_time) < 1e-9
        assert_same_skeleton(out / n, CLIP_A)
        gp = positions(m)
        assert np.abs(gp[0] - start).max() < 1e-2 and np.abs(gp[-1] - end).max() < 1e-2
        mids.append(gp[SCVAE_FRAMES // 2])
        assert_bvhio_agrees(out / n, (0, SCVAE_FRAMES // 2, SCVAE_FRAMES + 1))
    assert np.abs(mids[0] - mids[1]).max() > 1e-3          # different latent samples, different motion
    meta = json.loads((out / "infill.json").read_text())
    assert meta["frames"] == SCVAE_FRAMES and meta["samples"] == 3 and meta["start"].endswith(":5")


def test_cae_infill(runs, tmp_path, capsys):
    out = tmp_path / "out"
    run_cli(["infill", "--model", "cae", "--ckpt", runs["cae"], "--bvh", CLIP_A, "--gaps", "10:30,50:60",
             "--out", out], capsys)
    assert sorted(os.listdir(out)) == ["02_01_filled.bvh", "02_01_filled.npy", "infill.json"]
    src, m = read_bvh(CLIP_A), read_bvh(out / "02_01_filled.bvh")
    assert m.num_frames == src.num_frames
    assert_same_skeleton(out / "02_01_filled.bvh", CLIP_A)
    pos = np.load(out / "02_01_filled.npy")
    assert pos.shape == (src.num_frames, 21, 3) and np.all(np.isfinite(pos))
    known = np.ones(src.num_frames, bool)
    known[10:30] = known[50:60] = False
    np.testing.assert_allclose(positions(m)[known], positions(src)[known], atol=1e-3)   # known frames kept
    assert_bvhio_agrees(out / "02_01_filled.bvh", (0, 20, 55, src.num_frames - 1))


def test_interaction_infill(runs, tmp_path, capsys):
    out = tmp_path / "out"
    run_cli(["infill", "--model", "interaction", "--ckpt", runs["interaction"], "--a", f"{CLIP_A}:30",
             "--b", f"{CLIP_B}:30", "--key-a", f"{CLIP_A}:60", "--key-b", f"{CLIP_B}:70", "--frames", INTER_FRAMES,
             "--samples", 2, "--out", out], capsys)
    assert sorted(os.listdir(out)) == ["infill.json", "sample_00_A.bvh", "sample_00_B.bvh", "sample_01_A.bvh",
                                       "sample_01_B.bvh"]
    for who, src, s, k in (("A", CLIP_A, 30, 60), ("B", CLIP_B, 30, 70)):
        ref = positions(read_bvh(src))
        for i in range(2):
            path = out / f"sample_{i:02d}_{who}.bvh"
            m = read_bvh(path)
            assert m.num_frames == INTER_FRAMES + 2
            assert_same_skeleton(path, src)
            gp = positions(m)
            assert np.abs(gp[0] - ref[s]).max() < 1e-2 and np.abs(gp[-1] - ref[k]).max() < 1e-2
            assert_bvhio_agrees(path, (0, INTER_FRAMES // 2, INTER_FRAMES + 1))


def _png_colours(path) -> set:
    """The set of (r, g, b) colours of a PNG, after checking its signature."""
    from PIL import Image
    with open(path, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    with Image.open(path) as im:
        return {c[:3] for _, c in im.convert("RGB").getcolors(1 << 20)}


def test_infill_preview(runs, tmp_path, capsys, monkeypatch):
    """``--preview`` adds contact sheets (keyframes black, generated grey); ``--gif`` a GIF of both characters;
    a failing preview leaves nothing behind.  Same inputs as the tests above (compiled samplers are reused)."""
    from PIL import Image

    from inbetween_jax import viz
    black, grey = (0, 0, 0), (0x99, 0x99, 0x99)
    out = tmp_path / "s"
    run_cli(["infill", "--model", "scvae", "--ckpt", runs["scvae"], "--start", f"{CLIP_A}:5", "--end", f"{CLIP_B}:40",
             "--frames", SCVAE_FRAMES, "--samples", 3, "--out", out, "--seed", 1, "--preview"], capsys)
    assert sorted(os.listdir(out)) == ["infill.json"] + [f"sample_0{i}{e}" for i in range(3)
                                                          for e in (".bvh", "_sheet.png")] + ["samples_sheet.png"]
    for i in range(3):
        assert {black, grey} <= _png_colours(out / f"sample_0{i}_sheet.png")
    assert black in _png_colours(out / "samples_sheet.png")             # the samples overlaid, keyframes black
    summary = json.loads((out / "infill.json").read_text())
    assert len(summary["samples_spread_cm"]) == 3 and summary["samples_pairwise_cm"] >= 0
    out = tmp_path / "c"
    run_cli(["infill", "--model", "cae", "--ckpt", runs["cae"], "--bvh", CLIP_A, "--gaps", "10:30,50:60",
             "--out", out, "--preview"], capsys)
    assert sorted(os.listdir(out)) == ["02_01_filled.bvh", "02_01_filled.npy", "02_01_filled_sheet.png", "infill.json"]
    assert {black, grey} <= _png_colours(out / "02_01_filled_sheet.png")
    out = tmp_path / "i"
    run_cli(["infill", "--model", "interaction", "--ckpt", runs["interaction"], "--a", f"{CLIP_A}:30",
             "--b", f"{CLIP_B}:30", "--key-a", f"{CLIP_A}:60", "--key-b", f"{CLIP_B}:70", "--frames", INTER_FRAMES,
             "--samples", 2, "--out", out, "--gif"], capsys)                     # --gif implies --preview
    assert sorted(os.listdir(out)) == ["infill.json"] + [f"sample_0{i}{e}" for i in range(2) for e in (
        ".gif", "_A.bvh", "_A_sheet.png", "_B.bvh", "_B_sheet.png", "_pair_sheet.png")] + [
        "samples_sheet_A.png", "samples_sheet_B.png"]                           # each character's samples overlaid
    assert black in _png_colours(out / "samples_sheet_B.png")
    assert {black, grey} <= _png_colours(out / "sample_01_B_sheet.png")
    assert {black, grey} <= _png_colours(out / "sample_01_pair_sheet.png")     # both characters in one picture
    with Image.open(out / "sample_00.gif") as im:
        assert im.format == "GIF" and im.n_frames == INTER_FRAMES + 2

    def broken(*args, **kwargs):
        raise RuntimeError("drawing failed")
    monkeypatch.setattr(viz, "contact_sheet", broken)
    out = tmp_path / "broken"
    assert main(["infill", "--model", "cae", "--ckpt", runs["cae"], "--bvh", CLIP_A, "--gaps", "10:30,50:60",
                 "--out", str(out), "--preview"]) == 1
    assert "drawing failed" in capsys.readouterr().err
    assert not out.exists() and not [p for p in os.listdir(tmp_path) if p.startswith(".")]


def test_console_script_is_installed():
    exe = os.path.join(os.path.dirname(sys.executable), "inbetween")
    if not os.path.exists(exe):
        pytest.skip("console script not installed (pip install -e .)")
    res = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and "infill" in res.stdout
    res = subprocess.run([exe, "infill", "--model", "nope", "--ckpt", "x", "--out", "y"], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 2 and res.stderr.strip() == \
        "inbetween: error: unknown model 'nope' (choose scvae, cae, interaction)"


@pytest.mark.slow
def test_cli_on_trained_runs(tmp_path, capsys):
    """Run folders written by ``inbetween train scvae`` / ``interaction`` (2 steps) work with the CLI."""
    common = ["--source", "embedded", "--preset", "tiny", "--no-progress", "train.num_steps=2",
              "train.ckpt_every=2", "train.log_every=2"]
    for model in ("scvae", "interaction"):
        run_cli(["train", model, "--run-dir", str(tmp_path / model)] + common, capsys)
    run_cli(["infill", "--model", "scvae", "--ckpt", tmp_path / "scvae", "--start", CLIP_A, "--end", CLIP_B,
             "--frames", 10, "--samples", 2, "--out", tmp_path / "out_s"], capsys)
    m = read_bvh(tmp_path / "out_s" / "sample_01.bvh")
    assert m.num_frames == 12
    np.testing.assert_allclose(positions(m)[-1], positions(read_bvh(CLIP_B))[-1], atol=1e-2)
    run_cli(["infill", "--model", "interaction", "--ckpt", tmp_path / "interaction", "--a", CLIP_A, "--b", CLIP_B,
             "--key-a", f"{CLIP_A}:20", "--key-b", f"{CLIP_B}:20", "--frames", 30, "--out", tmp_path / "out_i"],
            capsys)
    assert read_bvh(tmp_path / "out_i" / "sample_00_B.bvh").num_frames == 32


HELP_ARGV = [["--help"], ["train", "--help"], ["bench", "--help"], ["infill", "--help"], ["preview", "--help"],
             ["demo", "--help"]] + [["train", m, "--help"] for m in ("scvae", "cae", "interaction")]


@pytest.mark.parametrize("argv", HELP_ARGV, ids=lambda a: "_".join(a).strip("-"))
def test_help_for_every_command_and_model(argv, capsys):
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert "usage: inbetween" in out and not err
    if len(argv) == 3:                                          # a model's help lists every config key
        presets = "improved, improved-velocity, cpu" if argv[1] == "scvae" else "improved, cpu"
        assert f"presets: {presets}, paper, tiny" in out and "train.num_steps = " in out and "train.lr = " in out
        assert "model." in out and "data." in out


def test_train_help_lists_models(capsys):
    assert main(["train", "--help"]) == 0
    out = capsys.readouterr().out
    assert all(m in out for m in ("scvae", "cae", "interaction")) and "key=value" in out


ERROR_ONLY = [
    ["infill", "--model", "cae", "--ckpt", "no_run", "--bvh", "missing.bvh", "--gaps", "1:2", "--out", "o"],
    ["preview", "missing.bvh"],
    ["train", "cae", "model.nope=1"],
    ["bench", "--source", "no/such/folder"],
]


@pytest.mark.parametrize("argv", ERROR_ONLY, ids=lambda a: a[0])
def test_input_errors_are_reported_before_jax_is_imported(argv, tmp_path):
    """An error-only command checks its arguments and files first: JAX is never imported."""
    code = ("import sys; from inbetween_jax.cli import main; rc = main(sys.argv[1:]); "
            "print('jax' in sys.modules, rc)")
    res = subprocess.run([sys.executable, "-c", code] + argv, capture_output=True, text=True, timeout=120,
                         cwd=tmp_path)
    assert res.stdout.split() == ["False", "2"], res.stdout + res.stderr
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("inbetween: error: ")


def test_outputs_have_ordinary_modes(runs, tmp_path, capsys):
    """Output folders and files get the modes ordinary programs give them (0777 / 0666 minus the umask)."""
    old = os.umask(0o022)
    try:
        out = tmp_path / "modes"
        run_cli(["infill", "--model", "cae", "--ckpt", runs["cae"], "--bvh", CLIP_A, "--gaps", "10:30",
                 "--out", out, "--preview"], capsys)
    finally:
        os.umask(old)
    assert (os.stat(out).st_mode & 0o777) == 0o755
    modes = {f: os.stat(out / f).st_mode & 0o777 for f in os.listdir(out)}
    assert set(modes.values()) == {0o644}, modes


def test_train_writes_one_run_format_and_refuses_another_config(tmp_path, capsys):
    """``inbetween train`` writes run.json (model, preset, config, skeleton, stats, provenance, history) and a
    checkpoint; resuming the folder with another config is refused in one line."""
    run = tmp_path / "run"
    common = ["train", "cae", "--source", "embedded", "--preset", "tiny", "--run-dir", run, "--no-progress",
              "train.log_every=1", "train.ckpt_every=1"]
    run_cli(common + ["train.num_steps=1"], capsys)
    meta = json.loads((run / "run.json").read_text())
    assert meta["model"] == "cae" and meta["preset"] == "tiny" and meta["config"]["train"]["num_steps"] == 1
    assert meta["skeleton"]["names"][0] and meta["stats"] and meta["data"]["source"] == "embedded"
    assert meta["history"][0]["steps"] == 1 and [d for d in os.listdir(run / "checkpoints") if d.isdigit()] == ["1"]
    run_cli(common + ["train.num_steps=2"], capsys)                  # a longer run resumes the same folder
    assert sorted(d for d in os.listdir(run / "checkpoints") if d.isdigit()) == ["1", "2"]
    assert main([str(a) for a in common + ["train.num_steps=3", "train.lr=0.5"]]) == 2
    assert "holds a cae run with another config" in capsys.readouterr().err
