"""End-to-end tests of the ``inbetween`` console script on the shipped CMU BVH files, one tiny run per model.

Runs are made once per test session (shared with ``test_hardening.py`` through :func:`cli_runs`): the CAE
trains 2 steps through ``experiments/train.py``; the S-CVAE and interaction runs hold their initial
parameters, saved in the run-folder layout their training writes (the S-CVAE with the training data's
statistics), because compiling either training step takes 30-60 s on two CPU cores --
``test_cli_on_trained_runs`` (slow) covers run folders written by ``experiments/train.py``.  Every written
BVH is read back with our reader and with the independent ``bvhio`` package.
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
ASSETS = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30")
CLIP_A, CLIP_B = os.path.join(ASSETS, "02_01.bvh"), os.path.join(ASSETS, "02_02.bvh")   # 86 and 76 frames
SCVAE_FRAMES, INTER_FRAMES = 8, 12


def cli_runs(tmp_path_factory) -> dict:
    """``{"scvae", "cae", "interaction"}`` run folders under the session's base temp folder (made once)."""
    base = tmp_path_factory.getbasetemp() / "cli_runs"
    runs = {m: str(base / m) for m in ("scvae", "cae", "interaction")}
    if not os.path.exists(base / "done"):
        from inbetween_jax.train import enable_compilation_cache
        enable_compilation_cache()         # before the first compilation (model construction compiles too)
        base.mkdir(exist_ok=True)
        _scvae_run(runs["scvae"])
        sys.path.insert(0, os.path.join(ROOT, "experiments"))
        import train
        assert train.main(["cae", "--source", "embedded", "--preset", "tiny", "--run-dir", runs["cae"],
                           "num_steps=2", "ckpt_every=2", "log_every=2"]) == 0
        _interaction_run(runs["interaction"])
        (base / "done").write_text("")
    return runs


def _scvae_run(run_dir: str) -> None:
    """A tiny S-CVAE run folder (run.json + checkpoints/0) holding the initial state of training."""
    import jax

    from inbetween_jax.configs.scvae import get_config
    from inbetween_jax.data import load_dataset
    from inbetween_jax.models import scvae_train
    from inbetween_jax.train import Checkpointer, config_to_dict
    cfg = get_config("tiny")
    windows = load_dataset("embedded", "train")
    init_fn = scvae_train.make_init_fn(cfg, scvae_train.compute_stats(windows), windows.local_quats.shape[2])
    os.makedirs(run_dir)
    with open(os.path.join(run_dir, "run.json"), "w") as f:
        json.dump({"source": "embedded", "variant": "tiny", "overrides": [], "num_windows": len(windows),
                   "num_joints": int(windows.local_quats.shape[2]), "config": config_to_dict(cfg)}, f)
    with Checkpointer(os.path.join(run_dir, "checkpoints")) as ck:
        ck.save(0, init_fn(jax.random.key(0)), {"step": 0, "seed": 0, "config": config_to_dict(cfg)}, force=True)


def _interaction_run(run_dir: str) -> None:
    """A tiny interaction run folder (interaction_meta.json + checkpoints/0) holding the initial state."""
    import jax

    from inbetween_jax.configs.interaction import get_config
    from inbetween_jax.models.interaction_data import _forward_axis
    from inbetween_jax.models.interaction_train import make_training
    from inbetween_jax.train import Checkpointer, config_to_dict
    cfg = get_config("tiny")
    skel = read_bvh(CLIP_A).skeleton
    fa = [float(v) for v in _forward_axis(skel)]
    _, init_fn, _, _ = make_training(cfg, skel.num_joints, fa)
    os.makedirs(run_dir)
    with open(os.path.join(run_dir, "interaction_meta.json"), "w") as f:
        json.dump({"source": "embedded", "variant": "tiny", "overrides": [], "config": config_to_dict(cfg),
                   "num_joints": skel.num_joints, "forward_axis": fa}, f)
    with Checkpointer(os.path.join(run_dir, "checkpoints")) as ck:
        ck.save(0, init_fn(jax.random.key(0)), {"step": 0, "seed": 0, "config": config_to_dict(cfg)}, force=True)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    return cli_runs(tmp_path_factory)


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
                                                          for e in (".bvh", "_sheet.png")]
    for i in range(3):
        assert {black, grey} <= _png_colours(out / f"sample_0{i}_sheet.png")
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
        ".gif", "_A.bvh", "_A_sheet.png", "_B.bvh", "_B_sheet.png")]
    assert {black, grey} <= _png_colours(out / "sample_01_B_sheet.png")
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
    """Run folders written by ``experiments/train.py scvae`` / ``interaction`` (2 steps) work with the CLI."""
    sys.path.insert(0, os.path.join(ROOT, "experiments"))
    import train
    common = ["--source", "embedded", "--variant", "tiny", "train.num_steps=2", "train.ckpt_every=2",
              "train.log_every=2"]
    for model in ("scvae", "interaction"):
        assert train.main([model, "--run-dir", str(tmp_path / model)] + common) == 0
    run_cli(["infill", "--model", "scvae", "--ckpt", tmp_path / "scvae", "--start", CLIP_A, "--end", CLIP_B,
             "--frames", 10, "--samples", 2, "--out", tmp_path / "out_s"], capsys)
    m = read_bvh(tmp_path / "out_s" / "sample_01.bvh")
    assert m.num_frames == 12
    np.testing.assert_allclose(positions(m)[-1], positions(read_bvh(CLIP_B))[-1], atol=1e-2)
    run_cli(["infill", "--model", "interaction", "--ckpt", tmp_path / "interaction", "--a", CLIP_A, "--b", CLIP_B,
             "--key-a", f"{CLIP_A}:20", "--key-b", f"{CLIP_B}:20", "--frames", 30, "--out", tmp_path / "out_i"],
            capsys)
    assert read_bvh(tmp_path / "out_i" / "sample_00_B.bvh").num_frames == 32
