"""CAE training on real clips: a tiny model overfits, a run resumes exactly, the CLIs run end to end."""
from __future__ import annotations

import json
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from flax import nnx

from inbetween_jax.configs.cae import get_config
from inbetween_jax.models import cae_infer as ci
from inbetween_jax.models.cae_train import load_trained, prepare_bank, train

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "experiments"))


def test_tiny_model_overfits_real_clips():
    """4 real 64-frame CMU clips, pure reconstruction: the L1 loss falls 4x and the joint error below 4 cm."""
    from inbetween_jax.models.cae import make_model
    cfg = get_config("tiny")
    bank, _, _ = prepare_bank("embedded", cfg)
    x = jnp.asarray(bank.clips(np.array([0, 11, 22, 30])))            # (4, 66, 64) real motion
    gd, params = nnx.split(make_model("cae", x.shape[1], (8, 8, 16, 16, 16)))
    tx = optax.adam(3e-3)

    @jax.jit
    def step(p, o):
        loss, g = jax.value_and_grad(lambda p: jnp.mean(jnp.abs(nnx.merge(gd, p)(x) - x)))(p)
        u, o = tx.update(g, o, p)
        return optax.apply_updates(p, u), o, loss

    opt = tx.init(params)
    losses = []
    for _ in range(300):
        params, opt, loss = step(params, opt)
        losses.append(float(loss))
    assert losses[-1] < 0.25 * losses[0], losses[::50]
    y = nnx.merge(gd, params)(x)
    err = ci.joint_errors(np.asarray(y), np.asarray(x), bank.normalizer, bank.num_joints)
    assert err.mean() < 4.0, err.mean()


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    run = str(tmp_path_factory.mktemp("cae") / "run")
    train(run, "embedded", "tiny", ["num_steps=4", "ckpt_every=2"], progress=False)
    return run


@pytest.mark.slow
def test_resume_matches_uninterrupted(tiny_run, tmp_path):
    state_resumed, logged, info = train(tiny_run, "embedded", "tiny", ["num_steps=8", "ckpt_every=2"],
                                        progress=False)
    assert [r["step"] for r in logged] == [6, 8]                       # resumed at 4, not from scratch
    fresh = str(tmp_path / "fresh")
    state_fresh, logged_fresh, _ = train(fresh, "embedded", "tiny", ["num_steps=8", "ckpt_every=2"],
                                         progress=False)
    for a, b in zip(jax.tree.leaves(state_resumed["params"]), jax.tree.leaves(state_fresh["params"])):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-6)
    assert logged[-1]["loss"] == pytest.approx(logged_fresh[-1]["loss"], rel=1e-5)
    m = load_trained(tiny_run)
    assert m.step == 8 and m.num_joints == 21


@pytest.mark.slow
def test_infill_cli_writes_positions_and_bvh(tiny_run, tmp_path):
    import infill_cae
    from inbetween_jax.data import read_bvh
    src = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30", "13_10.bvh")
    out = str(tmp_path / "filled")
    assert infill_cae.main(["--ckpt", tiny_run, "--bvh", src, "--out", out, "--gap", "100:160",
                            "--gap", "300:421"]) == 0
    pos = np.load(out + ".npy")
    inp, res = read_bvh(src), read_bvh(out + ".bvh")
    assert pos.shape == (inp.num_frames, 21, 3) and np.all(np.isfinite(pos))
    assert res.num_frames == inp.num_frames
    keep = ci.gap_frames(inp.num_frames, [(100, 160), (300, 421)]) > 0.5
    np.testing.assert_allclose(res.local_quats[keep][:, 1:], inp.local_quats[keep][:, 1:], atol=1e-3)
    # known frames keep the input trajectory
    np.testing.assert_allclose(pos[keep][:, 0, [0, 2]], inp.local_pos[keep][:, 0, [0, 2]], atol=0.05)
    summary = json.load(open(out + ".json"))
    assert summary["refit_frames"] == 60 + 121 and summary["error_cm_mean"] > 0
    assert infill_cae.main(["--ckpt", tiny_run, "--bvh", src, "--out", out + "2", "--joints", "lHand",
                            "--dropout", "0.3", "--noise", "0.5"]) == 0


@pytest.mark.slow
def test_bench_quick_runs(tmp_path):
    """``bench_cae.run(quick=True)`` trains 3-step models, labels them untrained and fills both tables."""
    import bench_cae
    r = bench_cae.run("embedded", str(tmp_path), None, quick=True)
    assert "UNTRAINED" in r["note"]
    assert set(r["table1"]) == {"linear", "holden1d", "vanilla", "cae"}
    assert r["table1"]["linear"][0] is None and all(len(v) == 3 for v in r["table1"].values())
    assert set(r["table2"]["cae"]) == {"sigma=1.0", "sigma=1.5", "p=0.3", "p=0.5"}
    assert os.path.isfile(tmp_path / "cae_bench.md")
