"""Interaction model training: a tiny model overfits real two-person windows (constructed pairs of the
shipped CMU clips); the training entry point writes a restorable run."""
from __future__ import annotations

import os
import sys

import jax
import numpy as np
import pytest

from inbetween_jax.configs.interaction import get_config
from inbetween_jax.models import interaction_data as idata
from inbetween_jax.models.interaction_train import make_training
from inbetween_jax.train import apply_overrides

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_tiny_model_overfits_real_pairs():
    cfg = apply_overrides(get_config("tiny"), ["train.lr=0.005", "train.ss_max=0.0", "train.w_adv=0.0"])
    pairs = idata.split_pairs(idata.load_pairs("embedded"), "train")
    J = pairs[0].feats.shape[2]
    nets, init_fn, step_fn, batch_fn = make_training(cfg, J, pairs[0].forward_axis, pairs)
    batch = batch_fn(0, jax.random.key(7))                       # one fixed batch of 4 real windows
    state = init_fn(jax.random.key(0))
    step = jax.jit(step_fn)
    first = None
    for i in range(250):
        state, m = step(state, batch, jax.random.key(i))
        if first is None:
            first = float(m["mse"])
    last = float(m["mse"])
    assert np.isfinite(last) and last < first / 5, (first, last)
    assert float(m["refine"]) < first                            # the refiner learns alongside


@pytest.mark.slow
def test_train_entry_point_and_restore(tmp_path):
    sys.path.insert(0, os.path.join(ROOT, "experiments"))
    from train_interaction import main
    from inbetween_jax.models.interaction_eval import restore_run
    run = str(tmp_path / "run")
    assert main(["--variant", "tiny", "--run-dir", run, "train.num_steps=4", "train.ckpt_every=2"]) == 0
    cfg, nets, params, meta = restore_run(run)
    assert meta["restored_step"] == 4 and cfg.model.hidden == get_config("tiny").model.hidden
    assert all(p["constructed"] for p in meta["pairs"])
