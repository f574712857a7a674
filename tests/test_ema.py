"""The parameters' moving average (``train.ema_decay``, :func:`inbetween_jax.train.optim.with_ema`): the recurrence
against a NumPy re-derivation, training itself unchanged, and a tiny CAE run whose loaded model uses the average,
resumed bitwise from a checkpoint."""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from inbetween_jax.train import ConfigError
from inbetween_jax.train.config import TrainConfig
from inbetween_jax.train.optim import EmaState, inference_params, make_optimizer, with_ema


def _quadratic_run(tx, steps=30):
    """SGD-style updates of tx on 0.5 |A p - b|^2 from a fixed start: the parameters after every update and the
    final optimiser state."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(5, 3)).astype(np.float32), rng.normal(size=5).astype(np.float32)
    params = {"p": jnp.asarray(rng.normal(size=3), jnp.float32)}
    state = tx.init(params)
    grad = jax.grad(lambda q: 0.5 * jnp.sum((a @ q["p"] - b) ** 2))
    trail = []
    for _ in range(steps):
        upd, state = tx.update(grad(params), state, params)
        params = optax.apply_updates(params, upd)
        trail.append(np.asarray(params["p"], np.float64))
    return trail, state, params


def test_ema_matches_a_numpy_recurrence_and_leaves_training_alone():
    decay = 0.9
    plain, _, p_plain = _quadratic_run(optax.sgd(0.05))
    trail, state, p_ema = _quadratic_run(with_ema(optax.sgd(0.05), decay))
    np.testing.assert_array_equal(np.asarray(p_plain["p"]), np.asarray(p_ema["p"]))      # same updates
    rng = np.random.default_rng(0)
    rng.normal(size=(5, 3)), rng.normal(size=5)                                           # as _quadratic_run draws
    ema = rng.normal(size=3).astype(np.float32).astype(np.float64)                       # the initial parameters
    for n, p in enumerate(trail, start=1):
        d = min(decay, (1.0 + n) / (10.0 + n))
        ema = d * ema + (1.0 - d) * p
    assert isinstance(state, EmaState) and int(state.count) == len(trail)
    np.testing.assert_allclose(np.asarray(state.ema["p"]), ema, rtol=1e-5, atol=1e-6)
    assert np.abs(np.asarray(state.ema["p"]) - trail[-1]).max() > 1e-4                   # not the last parameters


def test_inference_params_picks_the_average_only_where_it_exists():
    params = {"w": jnp.ones(3)}
    tx = make_optimizer(TrainConfig(ema_decay=0.5))
    fresh = tx.init(params)
    assert inference_params(params, fresh) is params                                      # count 0: no update yet
    _, stepped = tx.update({"w": jnp.ones(3)}, fresh, params)
    np.testing.assert_allclose(inference_params(params, stepped)["w"], stepped.ema["w"])
    assert not np.allclose(stepped.ema["w"], 1.0)
    assert inference_params(params, stepped, TrainConfig(ema_decay=0.5, ema_eval=False)) is params
    assert inference_params(params, make_optimizer(TrainConfig()).init(params)) is params  # off: no average kept
    members = jax.vmap(tx.init)({"w": jnp.ones((2, 3))})                                  # a leading member axis
    _, both = jax.vmap(lambda g, s, p: tx.update(g, s, p))({"w": jnp.ones((2, 3))}, members, {"w": jnp.ones((2, 3))})
    assert inference_params({"w": jnp.ones((2, 3))}, both)["w"].shape == (2, 3)
    for bad in (-0.1, 1.0):
        with pytest.raises(ConfigError, match="train.ema_decay"):
            make_optimizer(TrainConfig(ema_decay=bad))


def test_a_cae_run_with_the_average_resumes_bitwise_and_infers_with_it(tmp_path):
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.runner import train_model
    from inbetween_jax.train.run import load_run, restore_state
    over = ["train.num_steps=6", "train.ckpt_every=3", "train.ema_decay=0.8", "train.split=fit"]
    whole, _ = train_model("cae", "tiny", over, source="embedded", run_dir=str(tmp_path / "whole"), progress=False,
                           log=None)
    parts = str(tmp_path / "parts")
    train_model("cae", "tiny", over, source="embedded", run_dir=parts, progress=False, log=None, stop_at=3)
    train_model("cae", "tiny", over, source="embedded", run_dir=parts, progress=False, log=None)   # resumes
    a, b = load(load_run(whole, step=6)), load(load_run(parts, step=6))       # step 6: after the resume
    for x, y in zip(jax.tree.leaves(a.params), jax.tree.leaves(b.params)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    run = load_run(whole, step=6)
    target = jax.eval_shape(lambda: {"params": a.params, "opt_state": make_optimizer(
        dataclasses.replace(TrainConfig(), ema_decay=0.8)).init(a.params)})
    state = restore_state(run, target)
    assert int(state["opt_state"].count) == 6
    for used, avg, raw in zip(jax.tree.leaves(a.params), jax.tree.leaves(state["opt_state"].ema),
                              jax.tree.leaves(state["params"])):
        np.testing.assert_array_equal(np.asarray(used), np.asarray(avg))
    assert any(not np.array_equal(np.asarray(u), np.asarray(r))
               for u, r in zip(jax.tree.leaves(a.params), jax.tree.leaves(state["params"])))
    raw_run = dataclasses.replace(run, config={**run.config, "train": {**run.config["train"], "ema_eval": False}})
    for x, y in zip(jax.tree.leaves(load(raw_run).params), jax.tree.leaves(state["params"])):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
