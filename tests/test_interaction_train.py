"""Interaction model training: a tiny model overfits real two-person windows (constructed pairs of the
shipped CMU clips); the training entry point writes a run folder that ``infer.load`` restores and infills from."""
from __future__ import annotations

import argparse
import json
import os

import jax
import numpy as np
import pytest

from inbetween_jax.data.datasets import EMBEDDED_DIR
from inbetween_jax.errors import UserError
from inbetween_jax.models.interaction import infer
from inbetween_jax.models.interaction.config import get_config
from inbetween_jax.models.interaction.train import load_data, make_training
from inbetween_jax.runner import train_model
from inbetween_jax.train import apply_overrides
from inbetween_jax.train.run import load_run


def test_tiny_model_overfits_real_pairs():
    cfg = apply_overrides(get_config("tiny"), ["train.lr=0.005", "data.ss_max=0.0", "loss.w_adv=0.0"])
    training = make_training(cfg, load_data(cfg, "embedded"))
    batch = training.batch_fn(0, jax.random.key(7))              # one fixed batch of 4 real windows
    state = training.init_fn(jax.random.key(0))
    step = jax.jit(training.step_fn)
    first = None
    for i in range(250):
        state, m = step(state, batch, jax.random.key(i))
        if first is None:
            first = float(m["mse"])
    last = float(m["mse"])
    assert np.isfinite(last) and last < first / 5, (first, last)
    assert float(m["refine"]) < first                            # the refiner learns alongside


@pytest.mark.slow
def test_make_training_and_infer_round_trip_through_a_run_folder(tmp_path):
    """The training entry point (2 tiny steps, checkpoint every step) -> run folder -> infer.load restores the
    last step -> one infill of real BVH inputs: finite, right shape."""
    run_dir = str(tmp_path / "run")
    train_model("interaction", "tiny", ["train.num_steps=2", "train.ckpt_every=1", "train.split=fit",
                                        "train.keep_checkpoints=0"], source="embedded",
                run_dir=run_dir, progress=False, log=None)
    with open(os.path.join(run_dir, "selection.json")) as f:          # chosen on the held-out pair
        chosen = json.load(f)
    assert set(chosen["scores"]) == {"1", "2"} and all(np.isfinite(v) for v in chosen["scores"].values())
    run = load_run(run_dir, 2)
    trained = infer.load(run)
    assert trained.step == 2 and trained.cfg.model.hidden == get_config("tiny").model.hidden
    assert all(p["constructed"] for p in run.data["pairs"])
    assert run.extra["num_joints"] == trained.num_joints == len(run.skeleton["names"])
    a, b = os.path.join(EMBEDDED_DIR, "02_01.bvh"), os.path.join(EMBEDDED_DIR, "02_02.bvh")
    args = argparse.Namespace(a=f"{a}:30", b=f"{b}:30", key_a=f"{a}:70", key_b=f"{b}:70", frames=12, samples=1,
                              seed=0)
    res = infer.infill(args, run)
    assert [name for name, _, _ in res.samples] == ["sample_00"]
    _, motions, _ = res.samples[0]
    assert len(motions) == 2
    for m in motions:
        assert m.local_quats.shape[:2] == (12 + 2, run.extra["num_joints"])
        assert np.all(np.isfinite(m.local_quats)) and np.all(np.isfinite(m.local_pos))
        np.testing.assert_allclose(np.linalg.norm(m.local_quats, axis=-1), 1.0, atol=1e-5)
    assert res.summary["step"] == 2 and res.summary["frames"] == 12
    args.frames = 1000
    with pytest.raises(UserError, match="at most 60 frames"):
        infer.infill(args, run)
