"""PyTorch-eager S-CVAE reference (inbetween_jax/evaluation/torch_ref/scvae.py) on real CMU windows: its generator parameter
count equals the JAX model's, one training step returns a finite loss, 20 steps on one fixed batch reduce the
loss and (slow) with JAX's weights and zero latent noise three training steps reproduce JAX's losses.
torch is an optional (benchmark) dependency: without it the module is skipped."""
import dataclasses
import importlib.util
import os

import jax
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from inbetween_jax.data import load_dataset  # noqa: E402
from inbetween_jax.models.scvae import model as scvae  # noqa: E402
from inbetween_jax.models.scvae import train as T  # noqa: E402
from inbetween_jax.models.scvae.config import get_config  # noqa: E402
from inbetween_jax.models.scvae.features import TrainData, compute_stats  # noqa: E402

from inbetween_jax.evaluation.torch_ref import scvae as torch_scvae  # noqa: E402

TINY = get_config("tiny")


def _jax_count(cfg, num_joints):
    shapes = jax.eval_shape(lambda k: scvae.init_params(k, cfg.model, num_joints), jax.random.key(0))
    return sum(int(np.prod(x.shape)) for x in jax.tree.leaves(shapes))


def _variant(name):
    if name == "tiny":
        return TINY
    if name == "ablations":   # "w/o LSTM" and "w/o PM" change the parameter tree
        return dataclasses.replace(TINY, model=dataclasses.replace(TINY.model, encoder_lstm=False, phase_moe=False))
    return get_config(name)


@pytest.mark.parametrize("name", ["tiny", "paper", "cpu", "ablations"])
def test_param_count_matches_jax(name):
    cfg = _variant(name)
    assert torch_scvae.param_count(cfg, 21) == _jax_count(cfg, 21)


def test_built_tensors_match_param_count():
    params = torch_scvae.init_params(TINY.model, 21, seed=0)
    assert sum(x.numel() for x in torch_scvae.leaves(params["gen"])) == torch_scvae.param_count(TINY, 21)
    assert all(x.dtype == torch.float32 and x.requires_grad for x in torch_scvae.leaves(params))


@pytest.fixture(scope="module")
def step_inputs():
    """Tiny config, 4 real windows, L = max_length = trans_max + 1."""
    everything = load_dataset(None, "train")
    data = TrainData.from_windows(everything.take(slice(0, 4)))
    max_length = TINY.data.trans_max + 1
    batch = T.make_batch(data, np.arange(4), np.array([0, 5, 10, 20]), max_length, max_length)
    return data.q.shape[2], data.parents, compute_stats(everything), batch, max_length


@pytest.fixture()
def one_thread():
    """Single-threaded for speed on a shared CI machine (the module itself keeps torch's default)."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def test_one_step_finite_and_twenty_steps_reduce_the_loss(step_inputs, one_thread):
    assert torch_scvae.available()
    num_joints, parents, stats, batch, length = step_inputs
    step = torch_scvae.make_step(TINY, num_joints, parents, stats, batch, length, seed=0)
    first = step()
    assert isinstance(first, float) and np.isfinite(first)
    losses = np.array([first] + [step() for _ in range(19)])
    assert np.all(np.isfinite(losses))
    print(f"torch reference loss {losses[:3].mean():.3f} -> {losses[-3:].mean():.3f}")
    assert losses[-5:].mean() < 0.95 * losses[:5].mean(), losses


def test_length_must_match_batch(step_inputs):
    num_joints, parents, stats, batch, length = step_inputs
    with pytest.raises(ValueError):
        torch_scvae.make_step(TINY, num_joints, parents, stats, batch, length - 1)


@pytest.mark.slow   # compiles the JAX train step (~1 min on 2 busy cores)
def test_matches_jax_step_for_step_with_shared_weights(step_inputs, one_thread, monkeypatch):
    """Same weights in both and zero latent noise: three full training steps (generator loss, clip + AdamW,
    discriminator update) give the JAX losses, i.e. the reference computes the same function."""
    num_joints, parents, stats, batch, length = step_inputs
    state = T.make_init_fn(TINY, stats, num_joints)(jax.random.key(0))
    weights = {"gen": state["params"], "disc": state["disc"]}
    monkeypatch.setattr(jax.random, "normal", lambda key, shape, dtype=np.float32: jax.numpy.zeros(shape, dtype))
    train_step = jax.jit(T.make_train_step(TINY, parents, length))
    expected = []
    for _ in range(3):
        state, metrics = train_step(state, jax.tree.map(jax.numpy.asarray, batch), jax.random.key(1))
        expected.append(float(metrics["loss"]))
    monkeypatch.setattr(torch_scvae, "init_params", lambda *a, **k: jax.tree.map(
        lambda x: torch.tensor(np.asarray(x)).requires_grad_(), weights))
    monkeypatch.setattr(torch_scvae.torch, "randn", lambda shape, generator=None: torch.zeros(shape))
    step = torch_scvae.make_step(TINY, num_joints, parents, stats, batch, length)
    got = [step() for _ in range(3)]
    np.testing.assert_allclose(got, expected, rtol=1e-4)
