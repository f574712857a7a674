"""The S-CVAE's per-transition motion latent (``model.motion_latent``, models/scvae/motion_latent.py): the
Gaussian KL against its closed form, free bits, farthest-point draws, what the posterior sees, the decoder using
the latent, and training on real CMU windows."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.data import load_dataset
from inbetween_jax.models.scvae import model as M
from inbetween_jax.models.scvae import motion_latent as ML
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.models.scvae.features import TrainData, compute_stats
from inbetween_jax.train import apply_overrides

MAXLEN = 11
CFG = apply_overrides(get_config("tiny"), ["model.motion_latent=4", "model.residual=true", "train.lr=3e-3",
                                           "data.trans_start=10", "data.trans_max=10"])


@pytest.fixture(scope="module")
def setup():
    w = load_dataset(None, "train")
    data = TrainData.from_windows(w.take(slice(0, 8)))
    stats = jax.tree.map(jnp.asarray, compute_stats(w))
    batch = jax.tree.map(jnp.asarray, T.make_batch(data, np.arange(4), np.array([1, 3, 10, 20]), MAXLEN, MAXLEN))
    return data, stats, batch


def test_gaussian_kl_matches_the_closed_form_and_a_monte_carlo_estimate():
    rng = np.random.default_rng(0)
    mq, lq, mp, lp = (rng.normal(size=5) * s for s in (1.0, 0.5, 1.0, 0.5))
    kl = np.asarray(ML.gaussian_kl(mq, lq, mp, lp))
    sq, sp = np.exp(0.5 * lq), np.exp(0.5 * lp)
    closed = np.log(sp / sq) + (sq ** 2 + (mq - mp) ** 2) / (2 * sp ** 2) - 0.5
    np.testing.assert_allclose(kl, closed, rtol=1e-5)
    x = mq + sq * rng.normal(size=(400_000, 5))
    logq = -0.5 * ((x - mq) / sq) ** 2 - np.log(sq)
    logp = -0.5 * ((x - mp) / sp) ** 2 - np.log(sp)
    np.testing.assert_allclose((logq - logp).mean(0), kl, atol=0.02)
    assert np.allclose(ML.gaussian_kl(mq, lq, mq, lq), 0.0, atol=1e-6)


def test_free_bits_leave_the_posterior_unpenalised_below_the_floor_but_keep_fitting_the_prior():
    mu_q = jnp.full((3, 2), 0.3)
    lv_q = jnp.zeros((3, 2))
    prior = (jnp.zeros((3, 2)), jnp.zeros((3, 2)))       # KL per dimension 0.045 nats
    g_post, g_prior = jax.grad(lambda q, p: ML.motion_kl_terms(q, p, 0.5)[0], argnums=(0, 1))((mu_q, lv_q), prior)
    assert np.allclose(g_post[0], 0.0) and np.allclose(g_post[1], 0.0)
    assert np.all(np.asarray(g_prior[0]) < 0)            # the prior's mean moves toward the posterior's
    g_post0 = jax.grad(lambda q: ML.motion_kl_terms(q, prior, 0.0)[0])((mu_q, lv_q))
    assert np.all(np.asarray(g_post0[0]) > 0)            # without free bits the posterior is pulled to the prior
    _, nats = ML.motion_kl_terms((mu_q, lv_q), prior, 0.5)
    np.testing.assert_allclose(float(nats), 2 * 0.5 * 0.3 ** 2, rtol=1e-5)


def test_spread_draws_are_farther_apart_than_independent_draws():
    mu, lv = jnp.zeros((6, 3)), jnp.full((6, 3), np.log(4.0))
    keys = jax.random.split(jax.random.key(1), 8)
    plain, spread = ML.spread_draws(mu, lv, keys, 1), ML.spread_draws(mu, lv, keys, 8)
    assert plain.shape == spread.shape == (8, 6, 3)

    def min_gap(x):       # closest pair of the 8 draws, per batch row
        d = np.linalg.norm(np.asarray(x)[:, None] - np.asarray(x)[None], axis=-1)
        d[np.arange(8), np.arange(8)] = np.inf
        return d.min((0, 1))
    assert np.all(min_gap(spread) > min_gap(plain))
    shifted = ML.spread_draws(mu + 5.0, lv, keys, 8)     # same whitened picks, moved with the prior
    np.testing.assert_allclose(np.asarray(shifted) - 5.0, np.asarray(spread), atol=1e-5)
    np.testing.assert_allclose(ML.spread_draws(mu, lv, keys, 1, 0.5), 0.5 * plain, rtol=1e-5)   # temperature
    np.testing.assert_allclose(ML.spread_draws(mu + 1.0, lv, keys, 8, 0.0), 1.0, atol=1e-6)


def test_the_posterior_sees_the_gap_and_nothing_past_the_target(setup):
    data, stats, batch = setup
    params = M.init_params(jax.random.key(0), CFG.model, data.q.shape[2])["fwd"]["motion"]
    start, target, gt, _ = T.split_batch(batch)
    bq, br = M.base_path(start, target, 8, MAXLEN)
    mu, _ = ML.posterior(params, stats, gt, bq, br, 8)
    moved = dict(gt, r=gt["r"].at[:, 4].add(30.0))      # a gap frame moves
    past = dict(gt, r=gt["r"].at[:, 9].add(30.0))       # a frame after the target (time 8) moves
    assert float(jnp.abs(ML.posterior(params, stats, moved, bq, br, 8)[0] - mu).max()) > 1e-3
    np.testing.assert_allclose(ML.posterior(params, stats, past, bq, br, 8)[0], mu, atol=1e-6)


def test_the_decoder_uses_the_motion_latent(setup):
    data, stats, batch = setup
    params = M.init_params(jax.random.key(0), CFG.model, data.q.shape[2])
    for g in ("fwd", "bwd"):    # the residual head starts at zero (exactly Slerp); give it weights
        last = params[g]["dec"]["experts"][-1]
        last["w"] = 0.1 * jax.random.normal(jax.random.key(2), last["w"].shape)
    start, target, _, _ = T.split_batch(batch)
    roll = jax.jit(lambda m: M.rollout(params, CFG.model, stats, start, target, 10, jax.random.key(3), MAXLEN,
                                       motion=m)["out"]["r"])
    a, b = roll(jnp.zeros((4, 4))), roll(jnp.full((4, 4), 2.0))
    assert float(jnp.abs(a - b).max()) > 1e-4
    prior = jax.jit(lambda: M.rollout(params, CFG.model, stats, start, target, 10, jax.random.key(3), MAXLEN)["out"])
    np.testing.assert_array_equal(prior()["r"], prior()["r"])         # drawn from the prior: the key decides
    s = jax.jit(lambda k: M.sample(params, dataclasses.replace(CFG.model, search=2), stats, start, target, 10,
                                   jax.random.split(k, 3), MAXLEN))(jax.random.key(4))
    assert s["out"]["r"].shape == (3, 4, MAXLEN + 1, 3)
    assert float(jnp.std(s["out"]["r"][:, :, 1:10], 0).mean()) > 0


def test_training_with_the_motion_latent_is_finite_deterministic_and_reports_its_kl(setup):
    """With ``loss.prior_path`` (each window also rolled out from the prior's mean: twice the rows, deferred
    weight gradients included)."""
    data, stats, batch = setup
    cfg = apply_overrides(CFG, ["loss.prior_path=true"])
    init = jax.jit(T.make_init_fn(cfg, compute_stats(load_dataset(None, "train")), data.q.shape[2]))
    step = jax.jit(T.make_train_step(cfg, data.parents, MAXLEN))
    batch = dict(batch, length=jnp.int32(10))

    def losses(seed, n):
        state, out = init(jax.random.key(seed)), []
        for i in range(n):
            state, m = step(state, batch, jax.random.fold_in(jax.random.key(seed), i))
            out.append({k: float(v) for k, v in m.items()})
        return out
    hist = losses(0, 12)
    assert all(np.isfinite(h["loss"]) and h["kl_motion"] >= 0 for h in hist)
    assert max(h["kl_motion"] for h in hist) > 0.05      # the posterior moves off the prior
    assert losses(0, 3) == hist[:3]
