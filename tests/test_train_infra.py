"""Training infrastructure: config overrides, orbax checkpoints, metric logs, resumable driver.

Uses a tiny 2-layer MLP regression (synthetic data, optax adam) so every test is fast.  Run as a
script (``python tests/test_train_infra.py --kill-target RUN_DIR``) it trains and then hangs before
update 13, to be SIGKILLed by ``test_sigkill_resume_is_bitwise``.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from inbetween_jax.train import (Checkpointer, ConfigError, MetricLogger, apply_overrides, config_to_dict,
                                 run_training)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_RNG = np.random.default_rng(0)
X = _RNG.normal(size=(64, 4)).astype(np.float32)                    # (N, 4) inputs
Y = np.sin(X @ _RNG.normal(size=(4, 1))).astype(np.float32)          # (N, 1) targets
OPT = optax.adam(1e-2)
CONFIG = {"lr": 1e-2, "model": {"hidden": 16}}
STEPS = 20


def init_fn(key):
    """key -> {"params", "opt_state", "noise_key" (typed PRNG key), "step" (int32)}."""
    k1, k2, k3 = jax.random.split(key, 3)
    params = {"w1": jax.random.normal(k1, (4, 16)) * 0.5, "b1": jnp.zeros(16),
              "w2": jax.random.normal(k2, (16, 1)) * 0.5, "b2": jnp.zeros(1)}
    return {"params": params, "opt_state": OPT.init(params), "noise_key": k3, "step": jnp.int32(0)}


def _loss(params, x, y):
    h = jnp.tanh(x @ params["w1"] + params["b1"])
    return jnp.mean((h @ params["w2"] + params["b2"] - y) ** 2)


def train_step(state, batch, key, nan_at=None):
    """Pure step; uses both the driver key and the carried ``noise_key`` so both must round-trip."""
    x, y = batch
    noise_key, sub = jax.random.split(state["noise_key"])
    x = x + 0.01 * jax.random.normal(key, x.shape) + 0.01 * jax.random.normal(sub, x.shape)
    loss_fn = _loss
    if nan_at is not None:
        loss_fn = lambda p, x, y: _loss(p, x, y) * jnp.where(state["step"] == nan_at, jnp.nan, 1.0)
    loss, grads = jax.value_and_grad(loss_fn)(state["params"], x, y)
    updates, opt_state = OPT.update(grads, state["opt_state"], state["params"])
    new = {"params": optax.apply_updates(state["params"], updates), "opt_state": opt_state,
           "noise_key": noise_key, "step": state["step"] + 1}
    return new, {"loss": loss, "grad_norm": optax.tree.norm(grads)}


def batch_fn(step, key):
    """(step, key) -> (x (8, 4), y (8, 1)), deterministic."""
    idx = np.asarray(jax.random.randint(key, (8,), 0, X.shape[0]))
    return X[idx], Y[idx]


def _train(run_dir, num_steps=STEPS, seed=0, **kw):
    kw = {"log_every": 1, "ckpt_every": 5, **kw}
    return run_training(init_fn, train_step, batch_fn, CONFIG, run_dir, num_steps, seed=seed,
                        progress=False, **kw)


def _leaves(tree):
    return [np.asarray(jax.random.key_data(x)) if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)
            else np.asarray(x) for x in jax.tree.leaves(tree)]


def _assert_tree_equal(a, b):
    assert jax.tree.structure(a) == jax.tree.structure(b)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)):
        assert x.dtype == y.dtype and x.shape == y.shape
    for x, y in zip(_leaves(a), _leaves(b)):
        assert np.array_equal(x, y)


@pytest.fixture(scope="module", autouse=True)
def _compile_cache(tmp_path_factory):
    old = os.environ.get("INBETWEEN_JAX_CACHE")
    os.environ["INBETWEEN_JAX_CACHE"] = str(tmp_path_factory.mktemp("jax_cache"))
    yield
    if old is None:
        os.environ.pop("INBETWEEN_JAX_CACHE", None)
    else:
        os.environ["INBETWEEN_JAX_CACHE"] = old


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Uninterrupted 20-step run: (final state, logged rows)."""
    return _train(tmp_path_factory.mktemp("reference"))


# ---------------------------------------------------------------- (1) config overrides
@dataclasses.dataclass(frozen=True)
class _Model:
    dims: tuple = (64, 64)
    dropout: float = 0.1


@dataclasses.dataclass(frozen=True)
class _Cfg:
    lr: float = 1e-3
    steps: int = 100
    flag: bool = True
    name: str = "scvae"
    ckpt: object = None
    model: _Model = _Model()


def test_overrides_parse_types_and_reject_unknown_keys():
    base = _Cfg()
    cfg = apply_overrides(base, ["lr=3e-4", "steps=2000", "flag=false", "name=cae", "model.dims=32,16",
                                 "model.dropout=0", "ckpt=none"])
    assert cfg == _Cfg(lr=3e-4, steps=2000, flag=False, name="cae", model=_Model(dims=(32, 16), dropout=0.0))
    assert isinstance(cfg.model.dropout, float) and base == _Cfg()
    assert apply_overrides(base, ["model.dims=(8,)"]).model.dims == (8,)
    assert apply_overrides({"a": {"b": 1}}, ["a.b=3"]) == {"a": {"b": 3}}
    assert json.loads(json.dumps(config_to_dict(cfg)))["model"]["dims"] == [32, 16]
    for bad, key in [("model.dimz=3", "model.dimz"), ("steps=1.5", "steps"), ("flag=maybe", "flag"),
                     ("lr=fast", "lr"), ("model=3", "model"), ("nope.x=1", "nope.x"), ("model.dims=a,b", "model.dims")]:
        with pytest.raises(ConfigError) as err:
            apply_overrides(base, [bad])
        msg = str(err.value)
        assert f"'{key}'" in msg and "\n" not in msg, msg
    with pytest.raises(ConfigError, match="key=value"):
        apply_overrides(base, ["lr"])


# ---------------------------------------------------------------- (2) checkpoint round trip
def test_checkpoint_roundtrip_exact(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    state, step = init_fn(jax.random.key(1)), jax.jit(train_step)
    for i in range(3):
        state, _ = step(state, batch_fn(i, jax.random.key(i)), jax.random.key(100 + i))
    ck = Checkpointer("ckpts", max_to_keep=3, save_every=5)   # relative -> absolute
    assert os.path.isabs(ck.directory) and ck.latest_step() is None
    assert not ck.save(3, state)                                 # not a multiple of save_every
    for s in (5, 10, 15, 20):
        assert ck.save(s, state, extra_json={"step": s, "config": CONFIG})
    ck.close()
    ck = Checkpointer(tmp_path / "ckpts", max_to_keep=3, save_every=5)
    assert ck.latest_step() == 20 and ck.all_steps() == [10, 15, 20]
    for target in (jax.eval_shape(init_fn, jax.random.key(0)), init_fn(jax.random.key(0))):
        restored = ck.restore(20, target)
        _assert_tree_equal(restored, state)
        assert all(isinstance(x, jax.Array) for x in jax.tree.leaves(restored))
    assert ck.restore_extra(15) == {"step": 15, "config": CONFIG}
    ck.close()


# ---------------------------------------------------------------- (3) resume
def test_resume_matches_uninterrupted_run(tmp_path, reference):
    ref_state, ref_logged = reference
    _, first = _train(tmp_path, num_steps=10)
    state, second = _train(tmp_path, num_steps=STEPS)            # fresh driver, resumes from step 10
    _assert_tree_equal(state, ref_state)
    assert first + second == ref_logged
    with open(tmp_path / "metrics.csv") as f:
        steps = [int(line.split(",")[0]) for line in f.readlines()[1:]]
    assert steps == list(range(1, STEPS + 1))
    state2, third = _train(tmp_path, num_steps=STEPS)             # already done: no-op
    assert third == [] and Checkpointer(tmp_path / "checkpoints").latest_step() == STEPS
    _assert_tree_equal(state2, ref_state)


def test_sigkill_resume_is_bitwise(tmp_path, reference):
    _, ref_logged = reference
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([ROOT, os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--kill-target", str(tmp_path)],
                            env=env, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.time() + 60
        ckpt10, jsonl = tmp_path / "checkpoints" / "10", tmp_path / "metrics.jsonl"
        while not (ckpt10.is_dir() and jsonl.exists() and '"step": 12' in jsonl.read_text()):
            assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
            assert time.time() < deadline, "subprocess never reached step 12"
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    assert Checkpointer(tmp_path / "checkpoints").latest_step() == 10
    _, logged = _train(tmp_path)
    assert [r["step"] for r in logged] == list(range(11, STEPS + 1))
    assert logged == ref_logged[10:]                              # loss at steps 11..20, bitwise
    rows = [json.loads(line) for line in jsonl.read_text().splitlines()]
    assert rows == ref_logged                                     # killed rows 11, 12 were dropped, not duplicated


# ---------------------------------------------------------------- (4) NaN detection
def test_nan_loss_raises_and_is_not_checkpointed(tmp_path):
    step_fn = lambda s, b, k: train_step(s, b, k, nan_at=4)       # the 5th update is non-finite
    with pytest.raises(FloatingPointError, match=r"non-finite loss '(loss|grad_norm)' at step 5$"):
        run_training(init_fn, step_fn, batch_fn, CONFIG, tmp_path, STEPS, log_every=10, ckpt_every=3,
                     progress=False)
    assert Checkpointer(tmp_path / "checkpoints").all_steps() == [3]


# ---------------------------------------------------------------- (5) determinism, logger
def test_same_seed_same_curve(tmp_path, reference):
    _, ref_logged = reference
    _, logged = _train(tmp_path / "a", num_steps=STEPS, ckpt_every=100)
    assert logged == ref_logged
    _, other = _train(tmp_path / "b", num_steps=5, seed=1)
    assert [r["loss"] for r in other] != [r["loss"] for r in ref_logged[:5]]


def test_metric_logger_resume_truncates(tmp_path):
    with MetricLogger(tmp_path) as log:
        for s in range(1, 6):
            log.log(s, {"loss": np.float32(s)})
        log.log(6, {"loss": 6.0, "extra": jnp.asarray(1.0)})     # new column widens the CSV header
    lines = (tmp_path / "metrics.csv").read_text().splitlines()
    assert lines[0] == "step,loss,extra" and lines[-1] == "6,6.0,1.0" and len(lines) == 7
    with MetricLogger(tmp_path, resume_step=3) as log:
        log.log(4, {"loss": 40.0})
    lines = (tmp_path / "metrics.csv").read_text().splitlines()
    assert lines[0] == "step,loss" and [line.split(",")[0] for line in lines[1:]] == ["1", "2", "3", "4"]
    assert [json.loads(r)["loss"] for r in (tmp_path / "metrics.jsonl").read_text().splitlines()] == [1, 2, 3, 40]


if __name__ == "__main__" and sys.argv[1:2] == ["--kill-target"]:
    def _hanging_batch_fn(step, key):
        if step == 12:                                           # after updates 1..12 are logged
            time.sleep(600)
        return batch_fn(step, key)

    run_training(init_fn, train_step, _hanging_batch_fn, CONFIG, sys.argv[2], STEPS, log_every=1,
                 ckpt_every=5, progress=False)
