"""Shipped weights (:mod:`inbetween_jax.shipped`): export a tiny run, restore it from ``params.npz`` instead of
the orbax checkpoint, ``inbetween infill`` without ``--ckpt``, the bench's shipped sections, the size guard."""
import json
import os
import shutil

import numpy as np
import pytest

from conftest import CLIP_A, CLIP_B, ROOT

PACKAGE_WEIGHTS = os.path.join(ROOT, "inbetween_jax", "assets", "weights")
MAX_SHIPPED_MB = 25


def _train(model, steps, run_dir):
    from inbetween_jax.runner import train_model
    train_model(model, "tiny", [f"train.num_steps={steps}", "train.ckpt_every=2", "train.log_every=2"],
                "embedded", str(run_dir), progress=False, log=None)
    return str(run_dir)


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """Tiny CAE (2 training steps) and S-CVAE (initial checkpoint: a training step costs 30-60 s to compile)
    runs on the embedded CMU clips, exported as float16 into a temporary weights folder."""
    from inbetween_jax.shipped import export_run
    from inbetween_jax.train.loop import enable_compilation_cache
    enable_compilation_cache()
    base = tmp_path_factory.mktemp("shipped")
    root = str(base / "weights")
    runs, infos = {}, {}
    for model, steps in (("cae", 2), ("scvae", 0)):
        runs[model] = _train(model, steps, base / model)
        infos[model] = export_run(runs[model], root=root)
    return {"root": root, "runs": runs, "infos": infos}


def _loads(model, shipped):
    from inbetween_jax.models import REGISTRY
    from inbetween_jax.shipped import shipped_run
    from inbetween_jax.train.run import load_run
    infer = REGISTRY[model].module("infer")
    run = shipped_run(model, shipped["root"])
    assert run is not None and run.weights.endswith("params.npz") and run.step == shipped["infos"][model]["step"]
    return infer.load(run), infer.load(load_run(shipped["runs"][model]))


def test_cae_shipped_output_matches_checkpoint(shipped):
    from inbetween_jax.data.user_input import read_motion
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.models.cae.infer import fill
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    a, b = _loads("cae", shipped)
    motion = read_motion(CLIP_A)
    x = b.normalizer(body_frame_features(motion).features).T.astype(np.float32)        # (D, T)
    mask = frame_mask_image(gap_frames(motion.num_frames, [(10, 30), (50, 60)]), b.num_joints)
    ya, yb = fill(a, x, mask), fill(b, x, mask)
    assert ya.shape == x.shape and np.isfinite(ya).all()
    np.testing.assert_allclose(ya, yb, atol=2e-2 * float(np.abs(yb).max()))
    assert np.abs(ya - yb).max() > 0          # float16 weights: close, not bit-identical


def test_scvae_shipped_output_matches_checkpoint(shipped):
    from inbetween_jax.data.datasets import GENERIC_CONTACT_VELFACTOR
    from inbetween_jax.data.user_input import read_motion
    from inbetween_jax.models.scvae.features import keyframe_contacts
    from inbetween_jax.models.scvae.infer import infill_between
    a, b = _loads("scvae", shipped)
    for k in b.stats:                          # normalisation statistics ship in float32: exact
        np.testing.assert_array_equal(np.asarray(a.stats[k]), np.asarray(b.stats[k]))
    ma, mb = read_motion(CLIP_A), read_motion(CLIP_B)
    vf = b.extra.get("contact_velfactor", GENERIC_CONTACT_VELFACTOR)
    start = {"q": ma.local_quats[5], "r": ma.root_pos[5], "c": keyframe_contacts(ma, 5, vf)}
    end = {"q": mb.local_quats[40], "r": mb.root_pos[40], "c": keyframe_contacts(mb, 40, vf)}
    oa = infill_between(a, ma.skeleton, start, end, 10, 2)
    ob = infill_between(b, ma.skeleton, start, end, 10, 2)
    assert oa["q"].shape == (2, 12, ma.skeleton.num_joints, 4)
    np.testing.assert_allclose(oa["q"], ob["q"], atol=5e-3)
    np.testing.assert_allclose(oa["r"], ob["r"], atol=5e-3 * float(np.abs(ob["r"]).max()))


def test_export_keeps_only_inference_parameters(shipped):
    for model, keep in (("cae", ("params",)), ("scvae", ("params", "stats"))):
        info = shipped["infos"][model]
        folder = os.path.join(shipped["root"], model)
        assert sorted(os.listdir(folder)) == ["params.npz", "run.json"]
        with np.load(os.path.join(folder, "params.npz")) as z:
            names = list(z.files)
            assert all(n.split("/")[0] in keep for n in names), names[:5]
            assert not any(n.startswith(("opt", "disc")) for n in names)
            assert {z[n].dtype for n in names if n.startswith("params/")} == {np.dtype(np.float16)}
        meta = json.load(open(os.path.join(folder, "run.json")))
        rec = meta["shipped"]
        assert rec["step"] == info["step"] and rec["dtype"] == "float16" and rec["data_source"] == "embedded"
        assert rec["why"] == "latest checkpoint" and rec["keep"] == list(keep)
        assert info["bytes"] * 2 < info["checkpoint_bytes"], info          # no optimizer / discriminator state
    cae = shipped["infos"]["cae"]
    assert os.path.getsize(os.path.join(shipped["root"], "cae", "params.npz")) * 4 < cae["checkpoint_bytes"]


def test_export_sets_only_inference_switches(shipped, tmp_path):
    """``--set``: an inference-only switch lands in the shipped config (and is recorded); anything that would
    change what the parameters mean is refused with one line, before anything is written."""
    from inbetween_jax.shipped import export_run, shipped_run
    from inbetween_jax.train.run import RunError
    root = str(tmp_path / "w")
    export_run(shipped["runs"]["scvae"], root=root, inference=("model.search=3",))
    meta = json.load(open(os.path.join(root, "scvae", "run.json")))
    assert meta["config"]["model"]["search"] == 3 and meta["shipped"]["inference"] == ["model.search=3"]
    assert shipped_run("scvae", root).config["model"]["search"] == 3
    for bad in ("model.residual=false", "model.search=many"):
        with pytest.raises(RunError, match="--set model"):
            export_run(shipped["runs"]["scvae"], root=str(tmp_path / "bad"), inference=(bad,))
    assert not os.path.exists(tmp_path / "bad" / "scvae" / "params.npz")


@pytest.mark.parametrize("model", ["scvae", "cae", "interaction"])
def test_shipped_switch_records_match_the_config(model):
    """Each ``KEY=VALUE`` the shipped run.json records (export ``--set``, build-bank ``--set``) is the value its
    config holds, read by the model's own Config (the interaction model's record said bank_sample_weight=0.5 after
    build-bank had set 0.55)."""
    from inbetween_jax.shipped import config_with_overrides
    meta = json.load(open(os.path.join(PACKAGE_WEIGHTS, model, "run.json")))
    records = meta["shipped"]["inference"] + meta.get("bank", {}).get("switches", [])
    assert records
    config = config_with_overrides(model, meta["config"], [])       # as the model's Config reads it
    for item in records:
        assert config_with_overrides(model, meta["config"], [item]) == config, item


def test_merged_switches_replace_in_place():
    from inbetween_jax.banks import merged_switches
    assert merged_switches(["model.a=1", "model.b=2"], ["model.b=3", "model.c=4"]) == [
        "model.a=1", "model.b=3", "model.c=4"]
    assert merged_switches([], ["model.a=1"]) == ["model.a=1"]
    assert merged_switches(["model.a=1"], []) == ["model.a=1"]


def test_shipped_weights_in_the_package_stay_small():
    total = sum(os.path.getsize(os.path.join(d, f)) for d, _, files in os.walk(PACKAGE_WEIGHTS) for f in files)
    assert total <= MAX_SHIPPED_MB * 1024 * 1024, f"{total / 2 ** 20:.1f} MB shipped in {PACKAGE_WEIGHTS}"


def test_pyproject_ships_the_weights():
    text = open(os.path.join(ROOT, "pyproject.toml")).read()
    assert '"assets/weights/*/params.npz"' in text and '"assets/weights/*/run.json"' in text


def test_infill_without_ckpt_uses_shipped_weights(shipped, tmp_path, monkeypatch, capsys):
    from inbetween_jax.cli import main
    monkeypatch.setenv("INBETWEEN_WEIGHTS_DIR", shipped["root"])
    outs = {}
    for tag, ckpt in (("shipped", []), ("checkpoint", ["--ckpt", shipped["runs"]["cae"]])):
        out = tmp_path / tag
        assert main(["infill", "--model", "cae", *ckpt, "--bvh", CLIP_A, "--gaps", "10:30", "--out", str(out)]) == 0
        outs[tag] = np.load(out / "02_01_filled.npy")
        assert json.loads((out / "infill.json").read_text())["weights"] == tag
    assert "using the shipped cae weights (step 2, trained on embedded)" in capsys.readouterr().err
    np.testing.assert_allclose(outs["shipped"], outs["checkpoint"], atol=0.05)     # cm
    assert main(["infill", "--model", "cae", "--step", "7", "--bvh", CLIP_A, "--gaps", "10:30",
                 "--out", str(tmp_path / "s7")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--step 7" in err and "step 2 only" in err


def test_infill_without_shipped_weights_asks_for_ckpt(tmp_path, monkeypatch, capsys):
    from inbetween_jax.cli import main
    monkeypatch.setenv("INBETWEEN_WEIGHTS_DIR", str(tmp_path / "none"))
    out = tmp_path / "out"
    assert main(["infill", "--model", "cae", "--bvh", CLIP_A, "--gaps", "10:30", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no trained weights ship for --model cae" in err and "--ckpt" in err
    assert not out.exists() or not os.listdir(out)


def test_damaged_shipped_weights_give_one_line(shipped, tmp_path, monkeypatch, capsys):
    from inbetween_jax.cli import main
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.shipped import shipped_run
    from inbetween_jax.train.run import RunError
    root = tmp_path / "w"
    shutil.copytree(os.path.join(shipped["root"], "cae"), root / "cae")
    npz = root / "cae" / "params.npz"
    good = npz.read_bytes()
    npz.write_bytes(good[: len(good) // 2])                         # truncated download
    monkeypatch.setenv("INBETWEEN_WEIGHTS_DIR", str(root))
    assert main(["infill", "--model", "cae", "--bvh", CLIP_A, "--gaps", "10:30", "--out", str(tmp_path / "o")]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert len(err) == 1 and "params.npz: cannot read the shipped weights (BadZipFile" in err[0]
    with np.load(os.path.join(shipped["root"], "cae", "params.npz")) as z:     # one array of another shape
        arrays = {k: z[k] for k in z.files}
    name = next(k for k in arrays if arrays[k].ndim >= 2)
    arrays[name] = arrays[name][:-1]
    np.savez(npz, **arrays)
    with pytest.raises(RunError, match=f"{name} has shape .* the model expects"):
        load(shipped_run("cae"))
    del arrays[name]                                                # a missing parameter
    np.savez(npz, **arrays)
    with pytest.raises(RunError, match=f"{name} is missing"):
        load(shipped_run("cae"))
    os.remove(npz)                                                  # run.json alone: not shipped weights
    assert shipped_run("cae") is None


def test_bench_uses_shipped_weights_only_where_they_fit(shipped, monkeypatch):
    from types import SimpleNamespace

    from inbetween_jax.cli.bench_cmd import shipped_section
    from inbetween_jax.data import Skeleton
    from inbetween_jax.data.user_input import read_motion
    monkeypatch.setenv("INBETWEEN_WEIGHTS_DIR", shipped["root"])
    args = SimpleNamespace(results="unused", quick=True)
    skel = read_motion(CLIP_A).skeleton
    out = shipped_section("cae", "runs/cae", "lafan_dir", "lafan1", skel, args)
    assert out["rows"] == [] and "do not apply to LaFAN1" in out["markdown"]
    other = Skeleton.from_dict(dict(skel.to_dict(), names=["x" + n for n in skel.names]))
    out = shipped_section("scvae", "runs/scvae", "bvh_dir", "bvh-folder", other, args)
    assert out["rows"] == [] and "do not fit this source's" in out["markdown"]
    assert shipped_section("interaction", "runs/interaction", "embedded", "cmu-embedded", skel, args) is None


def test_bench_evaluates_shipped_interaction_weights_on_real_pairs(monkeypatch, tmp_path):
    """The pairs folder's single-person windows are on the raw 43-joint rig, the shipped interaction weights on the
    21 joints the pair loader keeps: the bench must hand the folder to the interaction bench, not skip it."""
    from types import SimpleNamespace

    from conftest import SHARED_DATA

    from inbetween_jax.cli import bench_cmd
    from inbetween_jax.data.user_input import read_motion
    from inbetween_jax.models import REGISTRY
    pairs = os.path.join(SHARED_DATA, "cmu_pairs")
    if not os.path.isdir(pairs):
        pytest.skip("shared CMU salsa data (cmu_pairs) not available")
    monkeypatch.delenv("INBETWEEN_WEIGHTS_DIR", raising=False)
    calls = []
    rows = [{"model": "interaction", "value": 1.0}, {"model": "interpolation", "value": 2.0}]
    spec = SimpleNamespace(benchmark=lambda *a: calls.append(a) or {"markdown": "table", "rows": rows})
    monkeypatch.setitem(REGISTRY, "interaction", spec)
    raw = read_motion(os.path.join(pairs, "60_01_scaled.bvh")).skeleton
    out = bench_cmd.shipped_section("interaction", str(tmp_path / "none"), pairs, "bvh-folder", raw,
                                    SimpleNamespace(results=str(tmp_path), quick=True))
    assert raw.num_joints == 43 and calls and calls[0][0] == pairs
    assert out["rows"][0]["weights"] == "shipped" and "shipped weights" in out["markdown"]
    assert "weights" not in out["rows"][1]                       # a baseline row beside the model's


@pytest.mark.slow
def test_bench_section_from_shipped_cae(shipped, tmp_path, monkeypatch):
    from types import SimpleNamespace

    from inbetween_jax.cli.bench_cmd import shipped_section
    from inbetween_jax.data.user_input import read_motion
    monkeypatch.setenv("INBETWEEN_WEIGHTS_DIR", shipped["root"])
    out = shipped_section("cae", str(tmp_path / "runs" / "cae"), "embedded", "cmu-embedded",
                          read_motion(CLIP_A).skeleton, SimpleNamespace(results=str(tmp_path / "res"), quick=True))
    assert out["rows"] and all((r.get("weights") == "shipped") == (r["model"] == "cae") for r in out["rows"])
    assert out["markdown"].startswith("**cae: shipped weights** (step 2, trained on embedded")


@pytest.mark.slow
@pytest.mark.parametrize("model", ["scvae", "interaction"])
def test_trained_run_round_trips_through_shipped_weights(model, tmp_path):
    """A few real training steps (optimizer state non-zero): the shipped parameters equal the checkpoint's
    within float16 rounding, and the file holds none of the optimizer state."""
    import jax

    from inbetween_jax.models import REGISTRY
    from inbetween_jax.shipped import export_run, shipped_run
    from inbetween_jax.train.run import load_run
    run_dir = _train(model, 2, tmp_path / model)
    info = export_run(run_dir, root=str(tmp_path / "w"))
    infer = REGISTRY[model].module("infer")
    a, b = infer.load(shipped_run(model, str(tmp_path / "w"))), infer.load(load_run(run_dir))
    pa, pb = a.params, b.params
    if model == "interaction":                 # the training-only groups come back as zeros
        assert all(not np.asarray(v).any() for v in jax.tree.leaves(pa["disc"]))
        pa, pb = {k: pa[k] for k in ("gen", "ref")}, {k: pb[k] for k in ("gen", "ref")}
    for x, y in zip(jax.tree.leaves(pa), jax.tree.leaves(pb)):
        np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-3, atol=1e-4)
    assert info["bytes"] * 2 < info["checkpoint_bytes"], info
