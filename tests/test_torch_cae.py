"""PyTorch reference of the CAE training step (inbetween_jax/evaluation/torch_ref/cae.py) on real CMU clips: from the same weights
and the same batch and mask its loss equals JAX's and so do the gradients of named convs, for the ``improved``
(residual + Hermite pre-fill + paste_known + gap weight 4) and ``cpu`` (the paper's method) presets at small
widths (3 units); its train step runs eagerly with a finite loss.  torch is an optional (benchmark) dependency: without it
the module is skipped."""
import dataclasses
import importlib.util
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from inbetween_jax.data import load_motions  # noqa: E402
from inbetween_jax.models.cae import losses, model  # noqa: E402
from inbetween_jax.models.cae.config import get_config  # noqa: E402
from inbetween_jax.models.cae.features import body_frame_features  # noqa: E402
from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames, joints_mask  # noqa: E402

from inbetween_jax.evaluation.torch_ref import cae as torch_cae  # noqa: E402


@pytest.fixture(autouse=True)
def one_thread():
    """Single-threaded for speed on a shared CI machine (the module itself keeps torch's default)."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def _small(preset):
    cfg = get_config(preset)
    return dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, channels=(4, 8, 8)))


@pytest.fixture(scope="module")
def clips():
    """4 real 64-frame clips (B, D, T) of the longest embedded CMU test motion, normalised per row, and a
    training-like mask (3 gaps, 3 joints removed from one clip)."""
    m = max(load_motions("embedded", "test"), key=lambda mm: mm.num_frames)
    f = body_frame_features(m).features
    f = (f - f.mean(0)) / (f.std(0) + 1e-3)
    x = np.stack([f[s:s + 64].T for s in (0, 100, 200, 300)]).astype(np.float32)
    j = (x.shape[1] - 3) // 3
    mask = np.stack([joints_mask(64, j, [5, 9, 17])] + [frame_mask_image(gap_frames(64, [gap]), j)
                                                          for gap in ((3, 20), (30, 61), (10, 12))])
    return jnp.asarray(x), jnp.asarray(mask)


def _random_params(cfg, d):
    """Random weights in the JAX tree (numpy draws: no per-leaf compiles): non-zero biases (no exact ties or zeros
    at the ReLUs and pools, where the two frameworks' sub-gradients differ) and a non-zero last conv (the residual
    form zero-initialises it, and then no gradient reaches the other convs)."""
    rng = np.random.default_rng(9)
    return jax.tree.map(lambda s: jnp.asarray(rng.uniform(-0.3, 0.3, s.shape), jnp.float32),
                        model.param_shapes(cfg, d))


@pytest.mark.parametrize("preset", ["improved", "cpu"])
def test_loss_and_gradients_match_jax(clips, preset):
    x, mask = clips
    cfg = _small(preset)
    params = _random_params(cfg, x.shape[1])

    def jax_loss(p):
        return losses.weighted_l1(model.apply(p, x * mask, cfg, mask), x, mask, cfg.loss.gap_weight)

    lj, gj = jax.jit(jax.value_and_grad(jax_loss))(params)   # one program compiles faster than op by op
    tp = torch_cae.params_from_jax(params)
    lt = torch_cae.loss(tp, torch.tensor(np.asarray(x)), torch.tensor(np.asarray(mask)), cfg)
    lt.backward()
    np.testing.assert_allclose(float(lt.detach()), float(lj), rtol=1e-5)
    for part, unit, conv in (("enc", 0, 0), ("enc", 2, 1), ("dec", 1, 0), ("dec", 2, 1)):
        g_jax = np.asarray(gj[part][unit][conv]["w"])
        g_torch = tp[part][unit][conv]["w"].grad.numpy().transpose(2, 3, 1, 0)
        assert np.abs(g_jax).max() > 0, (part, unit, conv)
        np.testing.assert_allclose(g_torch, g_jax, rtol=1e-3, atol=1e-5 * np.abs(g_jax).max())
        np.testing.assert_allclose(tp[part][unit][conv]["b"].grad.numpy(), np.asarray(gj[part][unit][conv]["b"]),
                                   rtol=1e-3, atol=1e-5 * np.abs(g_jax).max())


@pytest.mark.parametrize("fill", ["linear", "hermite"])
def test_prefill_matches_jax(clips, fill):
    x, mask = clips
    got = torch_cae.prefill(torch.tensor(np.asarray(x * mask)), torch.tensor(np.asarray(mask)), fill).numpy()
    np.testing.assert_allclose(got, np.asarray(model.prefill(x * mask, mask, fill)), rtol=1e-5, atol=1e-5)


def test_eager_train_step_runs(clips):
    x, _ = clips
    cfg = _small("improved")
    params = _random_params(cfg, x.shape[1])
    step = torch_cae.make_step(cfg, params, np.asarray(x), mu=30.0, matched=1.0)
    losses_ = [step() for _ in range(3)]
    assert step.backend == "eager" and all(np.isfinite(losses_))
    mask = torch_cae.training_mask(torch.Generator().manual_seed(0), 8, (x.shape[1] - 3) // 3, 64, 20.0,
                                   cfg.data.mask)
    assert mask.shape == (8, x.shape[1], 64) and 0.0 < float(mask.mean()) < 1.0
