"""What a user meets on a fresh clone: the shipped weights on raw 120 Hz CMU files, infill.json's frame numbers,
``inbetween preview`` on odd rigs, units and files, help texts, the data a training falls back to, ``bench`` beside
an unfinished run, a finished training run again, and the README's examples."""
from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest
from conftest import CLIP_A, ROOT, SHARED_DATA

from inbetween_jax.cli import main
from inbetween_jax.data import read_bvh

CMU_BVH = os.path.join(SHARED_DATA, "cmu_bvh")
SALSA = os.path.join(SHARED_DATA, "cmu_pairs", "60_01_scaled.bvh")
needs_cmu = pytest.mark.skipif(not os.path.isdir(CMU_BVH), reason="shared CMU data not beside the repository")
BLUE = np.array([0x1F, 0x77, 0xB4])          # viz.OTHER_COLOR: the poses of a plain preview


@pytest.fixture
def shipped_weights(monkeypatch):
    monkeypatch.delenv("INBETWEEN_WEIGHTS_DIR", raising=False)


def _run(argv, capsys) -> tuple:
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _held_keyframes(trained, skeleton, start, end, frames, num_samples, seed=0, forward_axis=None):
    """Stands in for the S-CVAE's sampler (what is checked is around it): the start pose held, then the end."""
    q = np.repeat(np.asarray(start["q"], np.float64)[None, None], frames + 2, axis=1).repeat(num_samples, 0)
    r = np.repeat(np.asarray(start["r"], np.float64)[None, None], frames + 2, axis=1).repeat(num_samples, 0)
    q[:, -1], r[:, -1] = end["q"], end["r"]
    return {"q": q, "r": r}


@needs_cmu
def test_scvae_end_keyframe_from_another_raw_file(shipped_weights, tmp_path, capsys, monkeypatch):
    """Two raw 43-joint 120 Hz files of different lengths: the end keyframe comes from the end file (not looked
    up in the start file's frames), and infill.json keeps the files' own frame numbers."""
    from inbetween_jax.models.scvae import infer
    monkeypatch.setattr(infer, "infill_between", _held_keyframes)
    start, end = os.path.join(CMU_BVH, "09_06.bvh"), os.path.join(CMU_BVH, "02_01.bvh")
    out = tmp_path / "out"
    rc, _, err = _run(["infill", "--model", "scvae", "--start", f"{start}:40", "--end", f"{end}:200", "--frames", 20,
                       "--out", out], capsys)
    assert rc == 0, err
    assert read_bvh(start).num_frames < 200                           # frame 200 lies beyond the start file
    m, src_s, src_e = read_bvh(out / "sample_00.bvh"), read_bvh(start), read_bvh(end)
    assert m.skeleton.names == src_s.skeleton.names and m.num_frames == 22
    np.testing.assert_allclose(m.root_pos[0], src_s.root_pos[40], atol=0.5)
    np.testing.assert_allclose(m.root_pos[-1], src_e.root_pos[200], atol=0.5)
    np.testing.assert_allclose(m.local_quats[-1], src_e.local_quats[200], atol=1e-4)   # the extra joints too
    meta = json.loads((out / "infill.json").read_text())
    assert meta["start"] == f"{start}:40" and meta["end"] == f"{end}:200"


@needs_cmu
def test_cae_infill_json_counts_the_files_own_frames(shipped_weights, tmp_path, capsys):
    raw = os.path.join(CMU_BVH, "02_01.bvh")
    out = tmp_path / "out"
    rc, _, err = _run(["infill", "--model", "cae", "--bvh", raw, "--gaps", "100:160", "--out", out], capsys)
    assert rc == 0, err
    assert "120 fps resampled" in err
    assert json.loads((out / "infill.json").read_text())["gaps"] == [[100, 160]]    # not 25:40 at 30 fps


def _first_frames(src: str, n: int, dst) -> str:
    """The first ``n`` frames of the BVH file ``src`` (one frame per line), written to ``dst``."""
    lines = open(src).read().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.strip().lower().startswith("frames"))
    dst.write_text("\n".join(lines[:k] + [f"Frames: {n}", lines[k + 1]] + lines[k + 2:k + 2 + n]) + "\n")
    return str(dst)


def _held_keyposes(trained, context, keys, frames, samples, seed=0, gate_info=None):
    return np.broadcast_to(keys[None, :, None], (samples, 2, frames) + keys.shape[1:]).copy()


@pytest.mark.skipif(not os.path.exists(SALSA), reason="shared salsa pairs not beside the repository")
def test_interaction_infill_json_counts_the_files_own_frames(shipped_weights, tmp_path, capsys, monkeypatch):
    """The dancers' 120 Hz files (their first 640 frames); the network is replaced by a stub (held keyposes):
    what is checked is the summary, not the rollout."""
    from types import SimpleNamespace

    from inbetween_jax.models.interaction import infer
    monkeypatch.setattr(infer, "infill_features", _held_keyposes)
    monkeypatch.setattr(infer, "load", lambda run: SimpleNamespace(step=run.step))
    a = _first_frames(SALSA, 640, tmp_path / "a.bvh")
    b = _first_frames(SALSA.replace("60_01", "61_01"), 640, tmp_path / "b.bvh")
    out = tmp_path / "out"
    rc, _, err = _run(["infill", "--model", "interaction", "--a", f"{a}:400", "--b", f"{b}:400", "--key-a",
                       f"{a}:600", "--key-b", f"{b}:604", "--frames", 10, "--out", out], capsys)
    assert rc == 0, err
    assert "120 fps resampled" in err
    meta = json.loads((out / "infill.json").read_text())
    assert (meta["a"], meta["key_a"], meta["key_b"]) == (f"{a}:400", f"{a}:600", f"{b}:604")   # not 100, 150, 151


def _bvh(path, frames_line: int, rows: int) -> str:
    """A one-joint BVH (root with position and rotation channels) of ``rows`` motion rows."""
    head = ["HIERARCHY", "ROOT Hips", "{", "  OFFSET 0 0 0",
            "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
            "  End Site", "  {", "    OFFSET 0 10 0", "  }", "}", "MOTION", f"Frames: {frames_line}",
            "Frame Time: 0.0333333"]
    path.write_text("\n".join(head + [f"{3 * i} 90 0 0 {5 * i} 0" for i in range(rows)]) + "\n")
    return str(path)


def _figure_rows(png) -> np.ndarray:
    from PIL import Image
    with Image.open(png) as im:
        rgb = np.asarray(im.convert("RGB")).astype(int)
    return np.flatnonzero((np.abs(rgb - BLUE).sum(-1) < 60).any(axis=1))


def test_preview_of_a_one_joint_skeleton(tmp_path, capsys):
    path = _bvh(tmp_path / "one.bvh", 12, 12)
    rc, out, err = _run(["preview", path, "--out", tmp_path / "o", "--gif"], capsys)
    assert rc == 0, err
    assert sorted(os.listdir(tmp_path / "o")) == ["one.gif", "one_sheet.png"]
    assert len(_figure_rows(tmp_path / "o" / "one_sheet.png")) > 3            # the lone joint is drawn


def test_motion_rows_beyond_the_frames_line_are_read_with_a_note(tmp_path, capsys):
    """The tolerant parser's design (data/bvh_parse.py) reads the declared frames; the CLI says what it dropped."""
    path = _bvh(tmp_path / "long.bvh", 8, 11)
    assert read_bvh(path).num_frames == 8
    rc, _, err = _run(["preview", path, "--out", tmp_path / "o"], capsys)
    assert rc == 0, err
    notes = [ln for ln in err.splitlines() if "note:" in ln]
    assert len(notes) == 1 and path in notes[0] and "3 frames" in notes[0] and "Frames: 8" in notes[0]


@pytest.mark.skipif(not os.path.exists(SALSA), reason="shared salsa pairs not beside the repository")
def test_preview_figures_are_as_tall_in_any_unit(tmp_path, capsys):
    """A centimetre file and a 1/128-unit file (1 unit about 1.28 m) give figures of about the same height."""
    heights = []
    for path in (CLIP_A, SALSA):
        rc, out, err = _run(["preview", path, "--frames", "0:40", "--every", "10", "--out", tmp_path], capsys)
        assert rc == 0, err
        rows = _figure_rows(out.split()[0])
        heights.append(rows.max() - rows.min())
    assert heights[0] > 100 and 0.75 < heights[1] / heights[0] < 1.33, heights


def _help_commands() -> list:
    """Every subcommand of ``inbetween`` (as its parser lists them) and ``train MODEL`` for every model."""
    import argparse

    from inbetween_jax.cli import build_parser
    from inbetween_jax.models import MODELS
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return [[]] + [[c] for c in sub.choices] + [["train", m] for m in MODELS]


def test_help_texts_hold_no_sphinx_markup(capsys):
    commands = _help_commands()
    assert {"train", "bench", "infill", "preview", "demo"} <= {c[0] for c in commands if c}
    for argv in commands:
        rc, out, err = _run(argv + ["--help"], capsys)
        assert rc == 0 and out.strip(), (argv, err)
        for markup in ("``", ":mod:", ":func:", ":class:", ":data:", ":meth:"):
            assert markup not in out, (argv, markup, out)


def test_train_help_states_the_models_default_preset(capsys):
    from inbetween_jax.models import REGISTRY
    _, out, _ = _run(["train", "--help"], capsys)
    text = " ".join(out.split())
    assert {s.default_preset for s in REGISTRY.values()} == {"improved"}
    assert "(default improved;" in text and "default cpu" not in text and "CPU preset" not in text
    _, out, _ = _run(["train", "scvae", "--help"], capsys)
    assert f"(default {REGISTRY['scvae'].default_preset})" in out


def test_default_training_data_falls_back_with_a_note(tmp_path, monkeypatch, capsys):
    """No usable shared mocap folder: a training without --source uses the embedded clips and says why."""
    from inbetween_jax.cli.train_cmd import default_source
    monkeypatch.delenv("LAFAN1_DIR", raising=False)
    monkeypatch.setenv("INBETWEEN_SHARED_DATA", str(tmp_path))            # an empty folder
    assert default_source("cae", None) is None
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "inbetween: note:" in err and "embedded" in err
    assert str(tmp_path) in err and "cmu_bvh" in err
    monkeypatch.setenv("INBETWEEN_SHARED_DATA", str(tmp_path / "missing"))
    assert default_source("scvae", None) is None and "INBETWEEN_SHARED_DATA" in capsys.readouterr().err
    assert default_source("cae", "embedded") == "embedded" and capsys.readouterr().err == ""


def _run_folder(path, steps=()):
    from inbetween_jax.models import REGISTRY
    from inbetween_jax.train.config import config_to_dict
    from inbetween_jax.train.run import write_run
    write_run(str(path), model="scvae", preset="tiny", overrides=[],
              config=config_to_dict(REGISTRY["scvae"].get_config("tiny")))
    os.makedirs(path / "checkpoints", exist_ok=True)
    for s in steps:
        os.makedirs(path / "checkpoints" / str(s))
        (path / "checkpoints" / str(s) / "x").write_text("x")
    return str(path)


def test_bench_uses_the_shipped_weights_beside_a_run_without_checkpoint(shipped_weights, tmp_path, monkeypatch,
                                                                       capsys):
    """`make train` stopped before its first checkpoint: the section comes from the shipped weights, says so, and
    only the model's own rows carry the weights tag."""
    from types import SimpleNamespace

    from inbetween_jax.cli import bench_cmd
    from inbetween_jax.data.user_input import read_motion
    from inbetween_jax.models import REGISTRY
    assert bench_cmd.why_not_run(str(tmp_path / "none")) == "no run in"
    empty = _run_folder(tmp_path / "scvae")
    assert bench_cmd.why_not_run(empty) == "no checkpoint yet in"
    assert bench_cmd.why_not_run(_run_folder(tmp_path / "done", [5])) is None
    rows = [{"model": "scvae", "value": 1.0}, {"model": "slerp", "value": 2.0}, {"model": "ground_truth", "value": 0}]
    monkeypatch.setitem(REGISTRY, "scvae", SimpleNamespace(benchmark=lambda *a: {"markdown": "table", "rows": rows}))
    out = bench_cmd.shipped_section("scvae", empty, "embedded", "cmu-embedded", read_motion(CLIP_A).skeleton,
                                    SimpleNamespace(results=str(tmp_path), quick=True), "no checkpoint yet in")
    assert out["markdown"].startswith("**scvae: shipped weights**")
    assert f"no checkpoint yet in `{empty}`" in out["markdown"]
    assert [r.get("weights") for r in out["rows"]] == ["shipped", None, None]
    assert "evaluating the shipped weights" in capsys.readouterr().err


def test_shipped_data_sources_are_shown_without_paths():
    from inbetween_jax.cli.bench_cmd import data_label
    assert data_label(os.path.join("..", "shared", "data", "cmu_pairs")) == "cmu_pairs"
    assert data_label("/somewhere/cmu_pairs/") == "cmu_pairs" and data_label("cmu") == "cmu"


def test_a_finished_training_run_again_says_it_is_complete(tmp_path, monkeypatch):
    """A run folder whose checkpoints reach train.num_steps: one "already complete" line, no progress bar, no
    new history entry (the training loop is a stub recording its progress switch)."""
    from inbetween_jax import train
    from inbetween_jax.runner import train_model
    calls = []
    monkeypatch.setattr(train, "run_training", lambda *a, **kw: calls.append(kw["progress"]) or (None, []))
    run_dir = str(tmp_path / "cae")
    overrides = ["train.num_steps=3"]
    for steps in ((), (3,)):                                  # a fresh run, then the finished one
        if steps:
            os.makedirs(os.path.join(run_dir, "checkpoints", "3"))
            open(os.path.join(run_dir, "checkpoints", "3", "x"), "w").close()
        lines = []
        train_model("cae", "tiny", overrides, "embedded", run_dir, progress=True, log=lines.append)
    assert calls == [True, False]
    assert [ln for ln in lines if "already complete" in ln] == [f"cae: training already complete (step 3 of 3) in "
                                                                f"{run_dir}"]
    assert len(json.load(open(os.path.join(run_dir, "run.json")))["history"]) == 1


def test_readme_examples_and_version_fit_a_fresh_clone():
    readme = open(os.path.join(ROOT, "README.md")).read()
    version = re.search(r'^version = "(\d+)\.(\d+)\.\d+"', open(os.path.join(ROOT, "pyproject.toml")).read(), re.M)
    assert f"version {version[1]}.{version[2]}" in readme
    infill = [ln for ln in readme.splitlines() if "inbetween infill" in ln]
    assert infill and not any("--ckpt runs/" in ln for ln in infill)        # the shipped weights: no run needed
    assert re.search(r"make bench .*about \d+ min", readme) and re.search(r"make test .*about \d+ min", readme)
