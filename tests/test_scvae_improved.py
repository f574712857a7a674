"""The S-CVAE ``improved`` preset's switches, each shown to change what it should (real CMU windows), and
checkpoint selection on the validation split."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.data import load_dataset
from inbetween_jax.models.scvae import losses as L
from inbetween_jax.models.scvae import model as M
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.models.scvae.features import TrainData, compute_stats

TINY = get_config("tiny")
MAXLEN = 11  # 10 transition frames


def with_model(cfg, **kw):
    return dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, **kw))


@pytest.fixture(scope="module")
def setup():
    w = load_dataset(None, "train")
    data = TrainData.from_windows(w.take(slice(0, 8)))
    stats = jax.tree.map(jnp.asarray, compute_stats(w))
    batch = jax.tree.map(jnp.asarray, T.make_batch(data, np.arange(4), np.array([1, 3, 10, 20]), MAXLEN, MAXLEN,
                                                   velocity=True))
    return data, stats, batch


def params_for(cfg, data):
    return M.init_params(jax.random.key(0), cfg.model, data.q.shape[2])


def test_improved_preset_departs_only_where_documented():
    imp, cpu = get_config("improved"), get_config("cpu")
    assert imp.model.residual and imp.model.decoder_target and imp.model.search > 1
    assert not (cpu.model.residual or cpu.model.decoder_target or cpu.model.search > 1)
    assert cpu.loss.kl_reduce == "sum" and imp.loss.kl_reduce == "mean"
    # same widths and the same budget: the bench compares them at equal cost
    for f in ("enc_hidden", "lstm_hidden", "dec_lstm_hidden", "expert_hidden", "latent_dim"):
        assert getattr(imp.model, f) == getattr(cpu.model, f)
    assert imp.train == cpu.train and imp.data.trans_max == cpu.data.trans_max == 50
    assert get_config("paper").model == dataclasses.replace(get_config("paper").model)


def test_untrained_residual_model_is_exactly_slerp_through_the_stitch(setup):
    data, stats, batch = setup
    cfg = with_model(TINY, residual=True, decoder_target=True)
    start, target, _, _ = T.split_batch(batch)
    res = M.rollout(params_for(cfg, data), cfg.model, stats, start, target, MAXLEN, jax.random.key(3), MAXLEN)
    q, r = M.interpolation_path(start, target, MAXLEN, MAXLEN)
    out_q = np.asarray(res["out"]["q"])
    np.testing.assert_allclose(out_q, np.asarray(M.quat_align(q, res["out"]["q"])), atol=2e-6)
    np.testing.assert_allclose(np.asarray(res["out"]["r"]), np.asarray(r), atol=1e-4)
    # the paper's decoder is not: it integrates its own velocities from the start frame
    plain = M.rollout(params_for(TINY, data), TINY.model, stats, start, target, MAXLEN, jax.random.key(3), MAXLEN)
    assert np.abs(np.asarray(plain["out"]["r"]) - np.asarray(r)).max() > 1.0


def test_root_response_middle_frames_follow_a_shifted_target(setup):
    """Shift the target root by +50 cm (same noise): the residual model's middle frame moves with it."""
    data, stats, batch = setup
    start, target, _, _ = T.split_batch(batch)
    shifted = dict(target, r=target["r"] + jnp.array([50.0, 0.0, 0.0]))
    mid = MAXLEN // 2
    expected = 50.0 * mid / MAXLEN
    for cfg, lo, hi in ((with_model(TINY, residual=True, decoder_target=True), 0.97, 1.03),):
        p = params_for(cfg, data)
        a = M.rollout(p, cfg.model, stats, start, target, MAXLEN, jax.random.key(5), MAXLEN)["out"]["r"][:, mid, 0]
        b = M.rollout(p, cfg.model, stats, start, shifted, MAXLEN, jax.random.key(5), MAXLEN)["out"]["r"][:, mid, 0]
        ratio = np.asarray(b - a) / expected
        assert np.all((ratio > lo) & (ratio < hi)), ratio


def test_decoder_target_switch_feeds_the_offset_embedding_to_the_decoder(setup):
    data, stats, batch = setup
    off = params_for(TINY, data)["fwd"]["dec"]["lstm"]
    on = params_for(with_model(TINY, decoder_target=True), data)["fwd"]["dec"]["lstm"]
    o = TINY.model.enc_out
    wx = lambda p: next(v for k, v in p.items() if k.startswith("w") and v.shape[0] in (TINY.model.latent_dim + 2 * o,
                                                                                   TINY.model.latent_dim + 3 * o))
    assert wx(on).shape[0] == wx(off).shape[0] + o
    cfg = with_model(TINY, decoder_target=True)
    p = M.pack_generator(params_for(cfg, data)["fwd"])
    start, _, _, _ = T.split_batch(batch)
    cur = dict(start, v=jnp.zeros_like(start["r"]), phase=jnp.zeros((4, 4)))
    carry = M.init_carry(cfg.model, 4)["dec"]
    z = jnp.zeros((4, cfg.model.latent_dim))
    e = jnp.ones((4, o))
    _, f1 = M.decode(p["dec"], cfg.model, carry, z, (e, e, e), cur, stats)
    _, f2 = M.decode(p["dec"], cfg.model, carry, z, (e, e, 2 * e), cur, stats)
    assert float(jnp.abs(f1["q"] - f2["q"]).max()) > 1e-6   # same z, other offset -> other pose


def test_kl_reduction_and_free_bits():
    kl = jnp.array([[0.5, 0.0, 2.0, 0.1]])
    lc = TINY.loss
    np.testing.assert_allclose(L.kl_term(kl, lc), [2.6], rtol=1e-6)
    np.testing.assert_allclose(L.kl_term(kl, dataclasses.replace(lc, kl_reduce="mean")), [0.65], rtol=1e-6)
    np.testing.assert_allclose(L.kl_term(kl, dataclasses.replace(lc, free_bits=0.25)), [0.5 + 0.25 + 2.0 + 0.25],
                               rtol=1e-6)


def test_latent_pair_search_keeps_the_best_meeting_candidate(setup):
    data, stats, batch = setup
    cfg = with_model(TINY, search=4)
    start, target, _, _ = T.split_batch(batch)
    p = params_for(cfg, data)
    keys = jax.random.split(jax.random.key(7), 2)
    best = M.sample(p, cfg.model, stats, start, target, MAXLEN, keys, MAXLEN)
    one = lambda kk: M.rollout(p, cfg.model, stats, start, target, MAXLEN, kk, MAXLEN)
    cands = jax.vmap(jax.vmap(one))(jax.vmap(lambda kk: jax.random.split(kk, 4))(keys))
    np.testing.assert_allclose(np.asarray(best["seam"]), np.asarray(cands["seam"]).min(1), rtol=1e-6)
    assert float(np.asarray(cands["seam"]).max(1).mean()) > float(np.asarray(best["seam"]).mean())
    assert best["out"]["q"].shape == (2,) + cands["out"]["q"].shape[2:]


def test_start_velocity_switch_uses_the_past_frame(setup):
    data, stats, batch = setup
    np.testing.assert_allclose(np.asarray(batch["v0"]), data.r[np.arange(4), [1, 3, 10, 20]]
                               - data.r[np.arange(4), [0, 2, 9, 19]], rtol=1e-6)
    start, target, _, _ = T.split_batch(batch)
    still = dict(start, v=jnp.zeros_like(start["v"]))
    for on in (False, True):
        cfg = with_model(TINY, start_velocity=on)
        p = params_for(cfg, data)
        a = M.rollout(p, cfg.model, stats, start, target, MAXLEN, jax.random.key(1), MAXLEN)["fwd"]["r"]
        b = M.rollout(p, cfg.model, stats, still, target, MAXLEN, jax.random.key(1), MAXLEN)["fwd"]["r"]
        assert (float(jnp.abs(a - b).max()) > 1e-6) == on


def test_length_schedule_ramp_mixed_lengths_and_scan_buckets(setup):
    data, _, _ = setup
    cfg = dataclasses.replace(TINY, data=dataclasses.replace(TINY.data, trans_start=2, trans_max=10, ramp_steps=100,
                                                             bucket=4))
    assert [T.transition_length(s, cfg, 8) for s in (0, 50, 100, 1000)] == [2, 6, 10, 10]
    assert [T.scan_length(n, cfg) for n in (3, 4, 5, 9, 11)] == [4, 4, 8, 11, 11]
    mixed = dataclasses.replace(cfg, data=dataclasses.replace(cfg.data, length_mode="mixed"))
    fn = T.batch_fn_factory(data, mixed)
    got = [fn(1000 + i, jax.random.key(i)) for i in range(12)]
    lengths = {int(b["length"]) for b in got}
    assert len(lengths) > 3 and min(lengths) >= 3 and max(lengths) <= 11
    for b in got:   # the batch is only as long as its bucket
        assert b["q"].shape[1] == T.scan_length(int(b["length"]), mixed) + 1
