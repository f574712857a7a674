"""CAE training on real clips: a tiny model overfits, a run resumes exactly, a run folder restores and infills,
the benchmark runs end to end."""
from __future__ import annotations

import argparse
import json
import os

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from inbetween_jax.evaluation.infilling import position_error
from inbetween_jax.models.cae import infer, model
from inbetween_jax.models.cae.config import get_config
from inbetween_jax.models.cae.masks import gap_frames
from inbetween_jax.models.cae.train import load_data, make_training
from inbetween_jax.runner import train_model
from inbetween_jax.train import apply_overrides
from inbetween_jax.train.run import load_run

ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "inbetween_jax", "assets", "cmu30")


def _train(run_dir, overrides, preset="tiny"):
    return train_model("cae", preset, overrides, source="embedded", run_dir=str(run_dir), progress=False, log=None)


def test_tiny_model_overfits_real_clips():
    """4 real 64-frame CMU clips, pure reconstruction: the L1 loss falls 4x and the joint error below 4 cm."""
    cfg = apply_overrides(get_config("tiny"), ["model.channels=8,8,16,16,16"])
    bank = load_data(cfg, "embedded").bank
    x = jnp.asarray(bank.clips(np.array([0, 11, 22, 30])))            # (4, 66, 64) real motion
    params = model.init_params(jax.random.key(0), cfg, x.shape[1])
    tx = optax.adam(3e-3)

    @jax.jit
    def step(p, o):
        loss, g = jax.value_and_grad(lambda p: jnp.mean(jnp.abs(model.apply(p, x, cfg) - x)))(p)
        u, o = tx.update(g, o, p)
        return optax.apply_updates(p, u), o, loss

    opt = tx.init(params)
    losses = []
    for _ in range(300):
        params, opt, loss = step(params, opt)
        losses.append(float(loss))
    assert losses[-1] < 0.25 * losses[0], losses[::50]
    y = model.apply(params, x, cfg)
    err, _ = position_error(np.asarray(y), np.asarray(x), bank.normalizer, bank.num_joints)
    assert err < 4.0, err


def test_make_training_pieces_and_meta():
    """``make_training`` on real clips: batch shapes, the curriculum's mu per epoch, finite step metrics."""
    cfg = get_config("tiny")
    data = load_data(cfg, "embedded")
    tr = make_training(cfg, data)
    assert tr.num_steps == 8 and tr.meta["extra"] == {"num_joints": 21, "clip_length": 64, "steps_per_epoch": 2}
    assert tr.meta["stats"]["mean"].shape == (66,) and len(tr.meta["data"]["files"]) == 2
    b = tr.batch_fn(0, jax.random.key(1))
    assert b["x"].shape == (4, 66, 64) and b["mu"] == 10.0
    assert tr.batch_fn(2 * 5, jax.random.key(1))["mu"] == 20.0        # epoch 5 (2 steps per epoch)
    state = tr.init_fn(jax.random.key(0))
    _, metrics = jax.jit(tr.step_fn)(state, b, jax.random.key(2))
    assert set(metrics) == {"loss", "hole_l1", "mu"} and all(np.isfinite(float(v)) for v in metrics.values())


def test_mirror_augmentation_in_batches():
    """data.mirror: p = 1 returns the mirror images of the clips p = 0 draws (the same clips: runs without the
    switch draw what they always drew), p = 0.5 mirrors some of a batch and not others."""
    from inbetween_jax.models.cae.features import mirror_clips, mirror_rows
    cfg = get_config("tiny")
    data = load_data(cfg, "embedded")
    plain = make_training(cfg, data).batch_fn(3, jax.random.key(7))["x"]
    flipped = make_training(apply_overrides(cfg, ["data.mirror=1"]), data).batch_fn(3, jax.random.key(7))["x"]
    perm, sign = mirror_rows(data.motions[0].skeleton)
    np.testing.assert_allclose(flipped, mirror_clips(plain, perm, sign, data.bank.normalizer), atol=1e-5)
    cfg8 = apply_overrides(cfg, ["data.mirror=0.5", "train.batch_size=16"])
    b0 = make_training(apply_overrides(cfg8, ["data.mirror=0"]), data).batch_fn(0, jax.random.key(3))["x"]
    b5 = make_training(cfg8, data).batch_fn(0, jax.random.key(3))["x"]
    same = np.all(b0 == b5, axis=(1, 2))
    assert 0 < same.sum() < 16


def test_tempo_copies_are_the_motions_played_faster():
    """data.tempo=2,0.5: each fast copy is its motion at half the frames, frame k the original's frame 2k (the same
    real motion twice as fast), each slow copy twice as long; the clip bank grows by the copies' clips; run.json
    names each file once; a speed of 0 is one line."""
    cfg = get_config("tiny")
    fast_cfg = apply_overrides(cfg, ["data.tempo=2,0.5"])
    plain, fast = load_data(cfg, "embedded"), load_data(fast_cfg, "embedded")
    n = len(plain.motions)
    assert len(fast.motions) == 3 * n and len(fast.bank.starts) > len(plain.bank.starts)
    assert all(abs(c.num_frames - 2 * m.num_frames) <= 2 for m, c in zip(plain.motions, fast.motions[2 * n:]))
    for m, c in zip(plain.motions, fast.motions[n:]):
        assert abs(c.fps - m.fps) < 1e-3 and abs(c.num_frames - (m.num_frames + 1) // 2) <= 1
        k = min(c.num_frames, (m.num_frames + 1) // 2)
        np.testing.assert_allclose(c.global_positions()[:k], m.global_positions()[:2 * k:2], atol=1e-3)
    assert make_training(fast_cfg, fast).meta["data"]["files"] == make_training(cfg, plain).meta["data"]["files"]
    with pytest.raises(ValueError, match="data.tempo"):
        load_data(apply_overrides(cfg, ["data.tempo=0"]), "embedded")


def test_improved_switches_in_training():
    """The improved switches on real clips: evaluation-matched gaps switch on at the curriculum's end, the
    untrained residual model's loss is its pre-fill's (``model.fill=hermite``: the limited Hermite fill), and
    gap_weight changes the loss of the same batch."""
    from inbetween_jax.baselines import hermite_fill
    from inbetween_jax.models.cae.losses import weighted_l1
    from inbetween_jax.models.cae.masks import training_mask
    cfg = apply_overrides(get_config("improved"), ["model.channels=4,4,8,8,8", "data.max_motions=2",
                                                   "data.clip_length=64", "train.batch_size=4"])
    tr = make_training(cfg, load_data(cfg, "embedded"))
    assert tr.meta["extra"]["steps_per_epoch"] == 20
    flags = [float(tr.batch_fn(s, jax.random.key(1))["matched"]) for s in (0, 119, 120, 1599)]
    assert flags == [0.0, 0.0, 1.0, 1.0]                                # curriculum 30..120 ends at epoch 6
    assert float(make_training(get_config("tiny"), load_data(get_config("tiny"), "embedded"))
                 .batch_fn(10 ** 4, jax.random.key(1))["matched"]) == 0.0
    b = tr.batch_fn(200, jax.random.key(1))
    state = tr.init_fn(jax.random.key(0))
    _, metrics = jax.jit(tr.step_fn)(state, b, jax.random.key(2))
    # the same mask as the step draws: the untrained model's loss is the Hermite fill's weighted L1
    x = np.asarray(b["x"])
    assert x.shape == (4, 66, 64)
    mask = np.asarray(training_mask(jax.random.key(2), 4, 21, 64, b["mu"], cfg.data.mask.sigma, cfg.data.mask.p_joint,
                                    cfg.data.mask.max_joints, b["matched"], (30, 60, 120), 0.25))
    assert cfg.model.fill == "hermite"
    want = float(weighted_l1(hermite_fill(x * mask, mask), x, mask, cfg.loss.gap_weight))
    assert float(metrics["loss"]) == pytest.approx(want, rel=1e-5)
    plain = make_training(apply_overrides(cfg, ["loss.gap_weight=1"]), load_data(cfg, "embedded"))
    _, m1 = jax.jit(plain.step_fn)(state, b, jax.random.key(2))
    want1 = float(weighted_l1(hermite_fill(x * mask, mask), x, mask, 1.0))
    assert float(m1["loss"]) == pytest.approx(want1, rel=1e-5) and abs(want1 - want) > 0.05 * want
    assert float(m1["hole_l1"]) == pytest.approx(float(metrics["hole_l1"]), rel=1e-6)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("cae") / "run"
    _train(run, ["train.num_steps=4", "train.ckpt_every=2"])
    return str(run)


def test_run_folder_round_trip(tmp_path):
    """Train 2 tiny steps, restore from the run folder alone, fill a real clip: finite, same shape."""
    run_dir, logged = _train(tmp_path / "run", ["train.num_steps=2", "train.log_every=1"])
    assert [r["step"] for r in logged] == [1, 2]
    trained = infer.load(load_run(run_dir))
    assert trained.step == 2 and trained.num_joints == 21 and trained.skeleton.num_joints == 21
    cfg = get_config("tiny")
    x = load_data(cfg, "embedded").bank.clips(np.array([0]))[0]      # (66, 64)
    mask = np.broadcast_to(gap_frames(64, [(20, 40)]), x.shape)
    y = infer.fill(trained, x, mask)
    assert y.shape == x.shape and np.all(np.isfinite(y))
    np.testing.assert_array_equal(infer.fill(trained, x, mask, keep_known=True)[mask > 0.5], x[mask > 0.5])


@pytest.mark.slow
def test_resume_matches_uninterrupted(tiny_run, tmp_path):
    _, logged = _train(tiny_run, ["train.num_steps=8", "train.ckpt_every=2"])
    assert [r["step"] for r in logged] == [6, 8]                       # resumed at 4, not from scratch
    fresh = tmp_path / "fresh"
    _, logged_fresh = _train(fresh, ["train.num_steps=8", "train.ckpt_every=2"])
    resumed, uninterrupted = infer.load(load_run(tiny_run)), infer.load(load_run(str(fresh)))
    for a, b in zip(jax.tree.leaves(resumed.params), jax.tree.leaves(uninterrupted.params)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-6)
    assert logged[-1]["loss"] == pytest.approx(logged_fresh[-1]["loss"], rel=1e-5)
    assert resumed.step == 8 and resumed.num_joints == 21


@pytest.mark.slow
def test_infill_writes_positions_and_bvh(tiny_run, tmp_path):
    from inbetween_jax.data import read_bvh, write_bvh
    src = os.path.join(ASSETS, "13_10.bvh")
    run = load_run(tiny_run)
    res = infer.infill(argparse.Namespace(bvh=src, gaps="100:160,300:421", samples=1, seed=0), run)
    (name, motions, generated), = res.samples
    assert name == "13_10_filled" and len(motions) == 1 and res.what == "known frames"
    res.extra_files["13_10_filled.npy"](str(tmp_path / "filled.npy"))
    write_bvh(str(tmp_path / "filled.bvh"), motions[0])
    pos = np.load(tmp_path / "filled.npy")
    inp, out = read_bvh(src), read_bvh(str(tmp_path / "filled.bvh"))
    assert pos.shape == (inp.num_frames, 21, 3) and np.all(np.isfinite(pos))
    assert out.num_frames == inp.num_frames
    keep = gap_frames(inp.num_frames, [(100, 160), (300, 421)]) > 0.5
    np.testing.assert_array_equal(generated, ~keep)
    np.testing.assert_allclose(out.local_quats[keep][:, 1:], inp.local_quats[keep][:, 1:], atol=1e-3)
    # known frames keep the input trajectory
    np.testing.assert_allclose(pos[keep][:, 0, [0, 2]], inp.local_pos[keep][:, 0, [0, 2]], atol=0.05)
    summary = json.loads(json.dumps(res.summary))
    assert summary["refit_frames"] == 60 + 121 and summary["error_cm_mean"] > 0 and summary["step"] == run.step
    other = infer.process_motion(infer.load(run), inp, joints=["lHand"], dropout=0.3, noise=0.5)
    assert other["positions"].shape == pos.shape and np.all(np.isfinite(other["positions"]))
    assert other["frames"].all() and other["error_cm"][0] > 0


def test_bench_skips_without_runs(tmp_path):
    from inbetween_jax.models.cae import bench
    for run_dir in (None, str(tmp_path)):
        r = bench.run("embedded", str(tmp_path / "results"), run_dir, quick=True)
        assert r["rows"] == [] and "skipped" in r["markdown"] and "inbetween train cae" in r["markdown"]
    assert not (tmp_path / "results").exists()


def test_validation_selection(tmp_path):
    """A ``train.split=fit`` run chooses its checkpoint on the held-out files (``selection.json``); an untrained
    residual model (zero last layer) scores exactly its Hermite fill's ratio to linear fill there."""
    from inbetween_jax.data import load_motions
    from inbetween_jax.evaluation.infilling import test_clips
    from inbetween_jax.models.cae import bench
    switches = ["model.residual=true", "model.paste_known=true", "model.fill=hermite"]
    run_dir, _ = _train(tmp_path / "run", switches + ["train.num_steps=2", "train.ckpt_every=1", "train.split=fit",
                                                      "train.keep_checkpoints=0"])
    with open(os.path.join(run_dir, "selection.json")) as f:
        chosen = json.load(f)
    assert set(chosen["scores"]) == {"1", "2"} and chosen["split"] == "val"
    assert chosen["scores"][str(chosen["step"])] == min(chosen["scores"].values())
    _train(tmp_path / "untrained", switches + ["train.num_steps=0"])
    untrained = load_run(str(tmp_path / "untrained"), 0)
    norm = infer.load(untrained).normalizer
    x = test_clips(load_motions("embedded", "val"), norm, bench.VAL_CLIP, bench.VAL_CLIP // 2)
    j = untrained.extra["num_joints"]
    want = [bench._time_matched(bench._baseline(f), x, norm, j, 30.0, None)["gaps"] for f in ("hermite", "linear")]
    assert set(want[0]) == {1, 2}                                   # a 4 s gap does not fit a 96-frame clip
    ratio = np.mean([want[0][s]["err"][0] / want[1][s]["err"][0] for s in (1, 2)])
    assert bench.val_score(untrained, "embedded") == pytest.approx(ratio, rel=1e-4)
    assert abs(ratio - 1.0) > 1e-3


def test_subject_split_run_selects_on_the_held_out_subjects(tmp_path, monkeypatch):
    """``train.split=fit-subjects`` trains on the files of the other subjects and asks for the held-out
    subjects' files (``val-subjects``) to score its checkpoints, recorded in ``selection.json``.  (The embedded
    set's held-out subject has only clips shorter than the score's 96 frames, so the score itself is taken on
    the test clips here.)"""
    from inbetween_jax.data import load_motions
    from inbetween_jax.data.datasets import split_files
    from inbetween_jax.models.cae import bench
    seen = []

    def val_motions(source, split="val"):
        seen.append(split)
        return load_motions(source, "test")
    monkeypatch.setattr(bench, "_val_motions", val_motions)
    run_dir, _ = _train(tmp_path / "run", ["train.num_steps=1", "train.ckpt_every=1", "train.split=fit-subjects",
                                           "train.keep_checkpoints=0", "data.max_motions=0"])
    with open(os.path.join(run_dir, "selection.json")) as f:
        chosen = json.load(f)
    assert chosen["split"] == "val-subjects" and set(seen) == {"val-subjects"}
    assert bench.run_val_split(load_run(run_dir)) == "val-subjects"
    trained_on = set(load_run(run_dir).data["files"])
    assert trained_on == {os.path.basename(f) for f in split_files("embedded", "fit-subjects")}
    assert not trained_on & {os.path.basename(f) for f in split_files("embedded", "val-subjects")}


def test_failed_selection_leaves_the_latest_step_and_says_how_to_select(tmp_path, monkeypatch):
    """When the validation score cannot be computed, training still finishes, the run opens at its latest
    checkpoint and the log says which command selects later."""
    from inbetween_jax.models.cae import bench

    def no_windows(run, source):
        raise ValueError("validation motion too short")
    monkeypatch.setattr(bench, "val_score", no_windows)
    lines = []
    run_dir, _ = train_model("cae", "tiny", ["train.num_steps=2", "train.ckpt_every=1", "train.split=fit"],
                             source="embedded", run_dir=str(tmp_path / "run"), progress=False, log=lines.append)
    said = [x for x in lines if "selection skipped" in x]
    assert len(said) == 1 and "too short" in said[0] and f"inbetween select-checkpoint {run_dir}" in said[0]
    assert not os.path.exists(os.path.join(run_dir, "selection.json")) and load_run(run_dir).step == 2


def test_only_process_0_writes_the_run_files(tmp_path, monkeypatch):
    """Under ``--num-processes N`` every process runs ``train_model``; only process 0 writes run.json, the wall
    time and selection.json (they raced on ``run.json.tmp``) and scores checkpoints, here seen from process 1."""
    import jax

    from inbetween_jax.models.cae import bench
    scored = []
    monkeypatch.setattr(bench, "val_score", lambda run, source: scored.append(run) or 1.0)
    monkeypatch.setattr(jax, "process_index", lambda *a, **k: 1)
    run_dir, logged = train_model("cae", "tiny", ["train.num_steps=2", "train.ckpt_every=1", "train.split=fit"],
                                  source="embedded", run_dir=str(tmp_path / "run"), progress=False, log=None)
    assert logged and not scored
    for name in ("run.json", "selection.json"):
        assert not os.path.exists(os.path.join(run_dir, name)), name


def test_every_position_scores_each_start_and_bootstraps_over_clips():
    """The every-position table: each clip's error is the mean over its gap starts of the protocol's own
    per-gap error (an independent route through ``position_error``); linear against itself is exactly 1 with a
    zero-width interval; the interval holds the ratio, is reproducible and widens with fewer clips."""
    from inbetween_jax.data import load_motions
    from inbetween_jax.data.features import Normalizer
    from inbetween_jax.evaluation.infilling import test_clips
    from inbetween_jax.models.cae import bench
    from inbetween_jax.models.cae.features import num_features
    from inbetween_jax.models.cae.masks import frame_mask_image
    motions = load_motions("embedded", "test")
    j = motions[0].skeleton.num_joints
    d = num_features(j)
    norm = Normalizer(np.zeros(d, np.float32), np.ones(d, np.float32))
    x = test_clips(motions, norm, 96, 96)[:6]
    herm, lin = bench._baseline("hermite"), bench._baseline("linear")
    got = bench.every_position(herm, x, norm, j, 30.0)
    assert set(got) == {1, 2}                                  # a 120-frame gap does not fit 96 frames
    assert got[1]["starts"] == list(range(10, 96 - 30 - 10 + 1, 10)) and got[2]["starts"] == [10, 20]
    n, _, t = x.shape
    for i in (0, 4):
        want = []
        for a in got[2]["starts"]:
            fm = np.broadcast_to(gap_frames(t, [(a, a + 60)]), (1, t))
            pred = herm(x[i:i + 1], frame_mask_image(fm, j))
            want.append(position_error(pred, x[i:i + 1], norm, j, frames=1.0 - fm)[0])
        assert got[2]["per_clip"][i] == pytest.approx(np.mean(want), rel=1e-5)
    ref = bench.every_position(lin, x, norm, j, 30.0)
    same = bench.ratio_interval(ref[1]["per_clip"], ref[1]["per_clip"])
    assert same["ratio"] == same["lo"] == same["hi"] == pytest.approx(1.0)
    ri = bench.ratio_interval(got[1]["per_clip"], ref[1]["per_clip"])
    assert ri["ratio"] == pytest.approx(got[1]["per_clip"].sum() / ref[1]["per_clip"].sum())
    assert ri["lo"] < ri["ratio"] < ri["hi"] and ri == bench.ratio_interval(got[1]["per_clip"], ref[1]["per_clip"])
    few = bench.ratio_interval(got[1]["per_clip"][:3], ref[1]["per_clip"][:3])
    assert few["hi"] - few["lo"] > 0 and ri["ratio"] != pytest.approx(1.0)


def test_bench_feeds_each_model_in_its_own_units():
    """A model trained with other statistics than the table's first model gets the same clips in its own units:
    a model that fills every gap with 0 in its own units (its mean) returns its mean, not the table's."""
    from inbetween_jax.data.features import Normalizer
    from inbetween_jax.models.cae import bench
    rng = np.random.default_rng(0)
    d, t = 12, 16
    table = Normalizer(rng.normal(size=d).astype(np.float32), rng.uniform(0.5, 2, d).astype(np.float32))
    own = Normalizer(rng.normal(size=d).astype(np.float32), rng.uniform(0.5, 2, d).astype(np.float32))

    class ZeroFill:
        normalizer = own

        def predict(self, x, mask):
            return x * mask
    x = rng.normal(size=(3, d, t)).astype(np.float32)
    mask = np.ones_like(x)
    mask[:, :, 5:9] = 0.0
    out = bench.in_table_units(ZeroFill(), table)(x, mask)
    np.testing.assert_allclose(out[:, :, 5:9], np.broadcast_to(table(own.mean)[None, :, None], (3, d, 4)),
                               rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(out[:, :, :5], x[:, :, :5], rtol=1e-5, atol=1e-5)   # known frames unchanged
    same = bench.in_table_units(type("Same", (ZeroFill,), {"normalizer": table})(), table)(x, mask)
    assert np.array_equal(same, x * mask)                                       # equal statistics: no conversion


@pytest.mark.slow
def test_bench_quick_runs(tmp_path):
    """The bench finds every run under a folder of run folders (one row each) and fills both tables."""
    from inbetween_jax.models.cae import bench
    runs = tmp_path / "runs" / "cae"
    for variant in ("holden1d", "vanilla", "cae"):
        _train(runs / variant, [f"model.variant={variant}", "train.num_steps=3"])
    _train(runs / "improved", ["model.residual=true", "model.paste_known=true", "train.num_steps=1"])
    _train(runs / "improved_mirror", ["model.residual=true", "model.paste_known=true", "train.num_steps=2",
                                      "model.mirror_average=true"])
    r = bench.run("embedded", str(tmp_path / "results"), str(runs), quick=True)
    # a second run of one variant gets its own row, keyed and labelled by its folder
    assert r["steps"] == {"holden1d": 3, "vanilla": 3, "cae": 3, "cae_residual": 1, "cae_residual:improved_mirror": 2}
    assert list(r["table1"]) == ["linear", "hermite", "holden1d", "vanilla", "cae", "cae_residual",
                                 "cae_residual:improved_mirror"]
    assert "| CAE, residual (improved) [improved_mirror] |" in r["markdown"]
    assert {x["variant"] for x in r["rows"] if x["model"] == "cae"} == {
        "holden1d", "vanilla", "cae", "cae_residual", "cae_residual:improved_mirror"}
    tm = r["time_matched"]
    assert [v["frames"] for v in tm["linear"]["gaps"].values()] == [30, 60, 120] and tm["linear"]["recon"] is None
    assert tm["cae_residual"]["recon"][0] == 0.0                         # known entries pasted back
    assert tm["cae"]["gaps"][2]["err"] == pytest.approx(r["table1"]["cae"][1])
    ratio = [x for x in r["rows"] if x["table"] == "cae_time_matched" and x["variant"] == "cae_residual"
             and x["frames"] == 30 and x["metric"] == "ratio_to_linear"]
    assert len(ratio) == 1 and 0.5 < ratio[0]["value"] < 1.5 and "Time-matched gaps" in r["markdown"]
    # every gap position: a ratio with its interval per learned row, the linear row in cm only
    ep = [x for x in r["rows"] if x["table"] == "cae_every_position" and x["variant"] == "cae_residual"
          and x["frames"] == 30]
    ep = {x["metric"]: x["value"] for x in ep}
    assert set(ep) == {"mpjpe_cm", "ratio_to_linear", "ratio_to_linear_lo95", "ratio_to_linear_hi95"}
    assert ep["ratio_to_linear_lo95"] <= ep["ratio_to_linear"] <= ep["ratio_to_linear_hi95"]
    assert {x["metric"] for x in r["rows"] if x["table"] == "cae_every_position" and x["model"] == "linear"} == {
        "mpjpe_cm"}
    assert "The same gaps at every position" in r["markdown"] and r["every_position"]["linear"][4]["starts"]
    assert r["table1"]["linear"][0] is None and all(len(v) == 3 for v in r["table1"].values())
    assert set(r["table2"]["cae"]) == {"sigma=1.0", "sigma=1.5", "p=0.3", "p=0.5"}
    assert set(r["bones"]) == {"holden1d", "vanilla", "cae", "cae_residual", "cae_residual:improved_mirror"}
    assert os.path.isfile(tmp_path / "results" / "cae_bench.md")
    assert "| Linear interpolation | n/a |" in r["markdown"]
    # the Hermite fill is a baseline row beside linear fill: no reconstruction / bones, a ratio to linear
    assert "| Hermite fill (limited cubic; baseline, not in paper) | n/a |" in r["markdown"]
    assert tm["hermite"]["recon"] is None and r["table1"]["hermite"][0] is None and "hermite" not in r["bones"]
    herm = [x for x in r["rows"] if x["table"] == "cae_time_matched" and x["model"] == "hermite"]
    assert len(herm) == 3 and all(0.5 < x["value"] < 1.5 for x in herm)
    rec = [x for x in r["rows"] if x["table"] == "cae_table1" and x["variant"] == "cae" and x["frames"] == 60
           and x["metric"] == "mpjpe_cm"]
    assert len(rec) == 1 and rec[0]["model"] == "cae" and rec[0]["value"] == pytest.approx(r["table1"]["cae"][1][0])
    lin = {x["metric"] for x in r["rows"] if x["model"] == "linear"}
    assert lin == {"mpjpe_cm", "mpjpe_std_cm"}
    # the linear row of a noise column is the noisy input itself
    assert r["table2"]["linear"]["sigma=1.0"][0] > r["table2"]["linear"]["p=0.3"][0]
    # a paste_known run returns a fully known clip unchanged: its noise cells are the noisy input's, and say so
    assert r["paste_known"] == ["cae_residual", "cae_residual:improved_mirror"]
    assert r["table2"]["cae_residual"]["sigma=1.0"] == pytest.approx(r["table2"]["linear"]["sigma=1.0"])
    rows = [x for x in r["markdown"].splitlines() if x.startswith("| CAE, residual (improved) |")]
    assert sum(x.count("(input: paste_known)") for x in rows) == 5     # reconstruction x 3, sigma x 2
    assert not any("paste_known" in x for x in r["markdown"].splitlines() if x.startswith("| CAE (ours) |"))
