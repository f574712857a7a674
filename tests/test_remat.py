"""``model.remat`` (:mod:`inbetween_jax.train.remat`) is a speed switch: the rollout's backward pass keeps fewer
intermediates and recomputes the rest, and the losses and gradients stay those of keeping everything.  Checked
on the S-CVAE's generator loss and the interaction model's generator objective, on real CMU windows, against
autodiff through the plain scan (``model.remat=``)."""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.data import load_dataset
from inbetween_jax.models.interaction import model as ia
from inbetween_jax.models.interaction.config import get_config as interaction_config
from inbetween_jax.models.interaction.losses import generator_objective
from inbetween_jax.models.interaction.train import training_batch
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config as scvae_config
from inbetween_jax.models.scvae.features import TrainData, compute_stats
from inbetween_jax.train import apply_overrides
from inbetween_jax.train.remat import REMAT_POLICIES, check_remat, remat_step

MAXLEN = 11


def _moved(params, key, scale=0.05):
    """Parameters with noise added, so zero-initialised residual heads pass gradients to every layer."""
    leaves, tree = jax.tree.flatten(params)
    keys = jax.random.split(key, len(leaves))
    return jax.tree.unflatten(tree, [a + scale * jax.random.normal(k, a.shape) for a, k in zip(leaves, keys)])


def _assert_same(plain, other, policy):
    (l0, g0), (l1, g1) = plain, other
    np.testing.assert_allclose(float(l1), float(l0), rtol=1e-6, err_msg=policy)
    for (path, a), b in zip(jax.tree_util.tree_leaves_with_path(g0), jax.tree.leaves(g1)):
        np.testing.assert_allclose(b, a, rtol=1e-4, atol=1e-7, err_msg=f"{policy}: {jax.tree_util.keystr(path)}")
    assert max(float(jnp.abs(g).max()) for g in jax.tree.leaves(g0)) > 1e-4      # the gradients are not all zero


def _has_checkpoint(fn, *args) -> bool:
    return "remat" in str(jax.make_jaxpr(fn)(*args))          # jax.checkpoint's primitive prints as remat2


@pytest.fixture(scope="module")
def scvae_setup():
    w = load_dataset(None, "train")
    data = TrainData.from_windows(w.take(slice(0, 8)))
    cfg = scvae_config("tiny")
    state = jax.jit(T.make_init_fn(cfg, compute_stats(w), data.q.shape[2]))(jax.random.key(0))
    batch = T.make_batch(data, np.arange(4), np.array([0, 3, 10, 20]), MAXLEN, MAXLEN)
    return cfg, data, state, batch


# the shipped default ("dots") in the default run; the other policy, and the heavier interaction gradient, are slow
POLICIES = [pytest.param(p, marks=[] if p == "dots" else pytest.mark.slow) for p in REMAT_POLICIES if p]


@pytest.mark.parametrize("policy", POLICIES)
def test_scvae_generator_gradient_is_unchanged(scvae_setup, policy):
    cfg0, data, state, batch = scvae_setup
    params = _moved(state["params"], jax.random.key(3))
    out = {}
    for p in ("", policy):
        cfg = dataclasses.replace(cfg0, model=dataclasses.replace(cfg0.model, remat=p))
        loss = lambda prm: T.generator_loss(prm, state["disc"], cfg, state["stats"], batch,  # noqa: E731
                                            jax.random.key(5), data.parents, MAXLEN)[0]
        assert _has_checkpoint(loss, params) == bool(p)          # the switch reaches the rollout
        out[p] = jax.jit(jax.value_and_grad(loss))(params)
    _assert_same(out[""], out[policy], policy)


def _interaction_loss(pair_train, policy):
    """(the interaction tiny model's generator objective as a function of its parameters, moved parameters)."""
    base = apply_overrides(interaction_config("tiny"), ["model.residual=true", "model.tta=true"])
    b = training_batch(pair_train, np.random.default_rng(1), base)
    b = dict(jax.tree.map(jnp.asarray, b), step=jnp.float32(0))
    params = _moved(ia.init_params(jax.random.key(0), base, b["x"].shape[3]), jax.random.key(4))
    fa = pair_train[0].forward_axis.astype(np.float32)
    cfg = apply_overrides(base, [f"model.remat={policy}"])
    return (lambda prm: generator_objective(prm, b, jax.random.key(0), cfg, fa)[0]), params


@pytest.mark.parametrize("policy", list(REMAT_POLICIES))
def test_interaction_switch_reaches_the_autoregression(pair_train, policy):
    assert _has_checkpoint(*_interaction_loss(pair_train, policy)) == bool(policy)


@pytest.mark.slow
@pytest.mark.parametrize("policy", [p for p in REMAT_POLICIES if p])
def test_interaction_generator_gradient_is_unchanged(pair_train, policy):
    out = {}
    for p in ("", policy):
        loss, params = _interaction_loss(pair_train, p)
        out[p] = jax.jit(jax.value_and_grad(loss))(params)
    _assert_same(out[""], out[policy], policy)


def test_unknown_policy_is_one_line():
    with pytest.raises(ValueError, match=r"unknown model.remat 'all'; choose one of '', 'dots', 'nothing'"):
        check_remat("all")
    with pytest.raises(ValueError, match="model.remat"):
        remat_step(lambda c, x: (c, x), "all")
    f = lambda c, x: (c, x)                                                                # noqa: E731
    assert remat_step(f, "") is f
