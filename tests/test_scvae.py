"""S-CVAE unit tests: schedules, shapes, exact target hit, diversity, ablation switches (real CMU windows)."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.data import load_dataset
from inbetween_jax.models.scvae import deferred_grads as D
from inbetween_jax.models.scvae import layers as nn
from inbetween_jax.models.scvae import model as M
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.models.scvae.features import TrainData, compute_stats, foot_phase, phase_labels

CFG = get_config("tiny")
MAXLEN = 11  # 10 transition frames


@pytest.fixture(scope="module")
def setup():
    w = load_dataset(None, "train")
    data = TrainData.from_windows(w.take(slice(0, 8)))
    stats = compute_stats(w)
    state = jax.jit(T.make_init_fn(CFG, stats, data.q.shape[2]))(jax.random.key(0))
    batch = T.make_batch(data, np.arange(4), np.array([0, 3, 10, 20]), MAXLEN, MAXLEN)
    return data, state, batch


def test_gamma_schedule_eq2():
    h, k = 5, 2   # L = 10
    g = np.asarray(M.gamma_schedule(jnp.arange(h + k + 1), h, k))
    np.testing.assert_allclose(g, [0, .2, .4, .6, .8, 5 / 7, 6 / 7, 1.0], rtol=1e-6)
    h2, k2 = M.split_sizes(31, 4)
    assert (int(h2), int(k2)) == (15, 4)
    assert int(M.split_sizes(6, 4)[1]) == 2  # buffer clipped to floor(L/2) - 1


def test_tta_embedding_values():
    e = np.asarray(nn.tta_embedding(jnp.array([0.0, 3.0]), 8, 10000.0))
    assert e.shape == (2, 8)
    np.testing.assert_allclose(e[0], [0, 1, 0, 1, 0, 1, 0, 1], atol=1e-7)
    np.testing.assert_allclose(e[1, :2], [np.sin(3.0), np.cos(3.0)], rtol=1e-6)
    np.testing.assert_allclose(e[1, 2], np.sin(3.0 / 10000 ** (2 / 8)), rtol=1e-5)


def test_phase_labels_square_wave():
    c = np.array([0] * 5 + [1] * 10 + [0] * 10 + [1] * 10 + [0] * 5, np.float32)
    phi, amp = foot_phase(c)
    np.testing.assert_allclose(phi[[5, 15, 25, 35]], [0.0, 0.5, 1.0, 1.5])   # touch-down 0, lift-off 0.5
    assert np.all(np.diff(phi) > 0) and amp[20] == pytest.approx(1.0, abs=0.05)
    lab = phase_labels(np.stack([c, c, 1 - c, 1 - c], -1)[None])
    assert lab.shape == (1, 40, 4)
    np.testing.assert_allclose(np.hypot(lab[0, :, 0], lab[0, :, 1]), amp, rtol=1e-5)


def test_progressive_schedule():
    cfg = dataclasses.replace(CFG, data=dataclasses.replace(CFG.data, trans_start=5, trans_max=50,
                                                            epochs_per_increment=2.0),
                              train=dataclasses.replace(CFG.train, batch_size=32))
    spe = 3200 // 32
    assert [T.transition_length(s, cfg, 3200) for s in (0, 2 * spe - 1, 2 * spe, 20 * spe, 10 ** 6)] == [5, 5, 6, 15, 50]


def _rollout(cfg, state, batch, key):
    s, t, _, _ = T.split_batch(batch)
    return M.rollout(state["params"], cfg.model, state["stats"], s, t, batch["length"], key, MAXLEN)


def test_shapes_target_hit_and_diversity(setup):
    data, state, batch = setup
    j = data.q.shape[2]
    s, t, _, _ = T.split_batch(batch)
    fn = jax.jit(lambda p, keys: M.sample(p, CFG.model, state["stats"], s, t, batch["length"], keys, MAXLEN))
    res = fn(state["params"], jax.random.split(jax.random.key(1), 3))
    steps = MAXLEN // 2 + CFG.model.buffer_k
    assert res["fwd"]["q"].shape == (3, 4, steps, j, 4) and res["bwd"]["r"].shape == (3, 4, steps, 3)
    assert res["out"]["q"].shape == (3, 4, MAXLEN + 1, j, 4) and res["kl_fwd"].shape == (3, 4, steps, CFG.model.latent_dim)
    out = jax.device_get(res["out"])
    # the stitched sequence starts at the start keyframe and ends exactly on the target keyframe
    for name, frame in (("q", MAXLEN), ("r", MAXLEN), ("q", 0), ("r", 0)):
        want = np.broadcast_to(batch[name][:, frame], out[name][:, :, frame].shape)
        np.testing.assert_array_equal(out[name][:, :, frame], want)
    # frames 1..h-K come from the forward generator, h+K+1..L-1 from the backward one, blend in between
    h, k = MAXLEN // 2, CFG.model.buffer_k
    np.testing.assert_allclose(out["r"][:, :, 1:h - k + 1], res["fwd"]["r"][:, :, :h - k], atol=1e-6)
    bi = MAXLEN - 1 - np.arange(h + k + 1, MAXLEN)
    np.testing.assert_allclose(out["r"][:, :, h + k + 1:MAXLEN], res["bwd"]["r"][:, :, bi], atol=1e-6)
    assert np.all(np.isfinite(out["q"])) and np.allclose(np.linalg.norm(out["q"], axis=-1), 1, atol=1e-5)
    # different keys -> different transitions
    assert np.abs(out["r"][0, :, 1:MAXLEN] - out["r"][1, :, 1:MAXLEN]).max() > 1e-4


SWITCHES = ["bidirectional", "latent_interp", "aligning", "phase_moe", "encoder_lstm", "discriminators",
            "stitch_loss"]


def _ablated_params(params, name):
    """Base parameters adapted to a switch that removes a module, so only the switch differs."""
    p = jax.tree.map(np.asarray, params)
    for g in ("fwd", "bwd"):
        if name == "encoder_lstm":      # MLP in place of the LSTM: reuse the LSTM's input weights of one gate
            wx = p[g]["enc"].pop("lstm")["wx"]
            p[g]["enc"]["mlp"] = [{"w": wx[:, :wx.shape[1] // 4], "b": np.zeros(wx.shape[1] // 4, np.float32)}]
        if name == "phase_moe":         # one MLP expert, no gating
            p[g]["dec"].pop("gating")
            p[g]["dec"]["experts"] = [{"w": l["w"][:1], "b": l["b"][:1]} for l in p[g]["dec"]["experts"]]
    return p


def test_each_ablation_switch_changes_the_computation(setup):
    data, state, batch = setup
    key = jax.random.key(3)
    stats, disc = state["stats"], state["disc"]
    with jax.disable_jit():   # eager: 8 configurations without 8 compilations
        base_loss, (_, base_out, _) = T.generator_loss(state["params"], disc, CFG, stats, batch, key, data.parents, MAXLEN)
        for name in SWITCHES:
            cfg = dataclasses.replace(CFG, model=dataclasses.replace(CFG.model, **{name: False}))
            params = _ablated_params(state["params"], name)
            if name in ("discriminators", "stitch_loss"):   # loss-only switches: same motion, different loss
                loss, (m, out, _) = T.generator_loss(params, disc, cfg, stats, batch, key, data.parents, MAXLEN)
                np.testing.assert_allclose(out["r"], base_out["r"], atol=1e-5)
                assert abs(float(loss) - float(base_loss)) > 1e-4, f"switching off {name} changed nothing"
            else:
                out = _rollout(cfg, dict(state, params=params), batch, key)["out"]
                diff = float(np.abs(np.asarray(out["r"]) - np.asarray(base_out["r"])).max())
                assert diff > 1e-4, f"switching off {name} changed nothing"
                # every variant still starts and ends on the keyframes
                np.testing.assert_array_equal(np.asarray(out["q"])[:, MAXLEN], batch["q"][:, MAXLEN])


def test_packed_layers_equal_plain_layers():
    """The rollout's packed LSTM / shared-carry LSTM / packed MoE compute exactly what the plain layers do."""
    f = nn.ParamFactory()
    tree = {"lstm": nn.init_lstm(f, 6, 5), "moe": nn.init_moe(f, (5, 7, 3), 4)}
    p = f.materialize(tree, jax.random.key(0))
    ks = jax.random.split(jax.random.key(1), 5)
    x1, x2 = jax.random.normal(ks[0], (3, 6)), jax.random.normal(ks[1], (3, 6))
    carry = (jax.random.normal(ks[2], (3, 5)), jax.random.normal(ks[3], (3, 5)))
    (h_ref, c_ref), y1 = nn.lstm(p["lstm"], carry, x1)
    _, y2 = nn.lstm(p["lstm"], carry, x2)
    (h_pk, c_pk), y_pk = nn.lstm_packed(nn.pack_lstm(p["lstm"]), carry, x1)
    np.testing.assert_allclose(y_pk, y1, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(c_pk, c_ref, rtol=1e-5, atol=1e-6)
    (h_sh, c_sh), z1, z2 = nn.lstm_shared_carry(p["lstm"], carry, x1, x2)
    np.testing.assert_allclose(z1, y1, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(z2, y2, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(c_sh, c_ref, rtol=1e-5, atol=1e-6)
    alpha = jax.nn.softmax(jax.random.normal(ks[4], (3, 4)), -1)
    np.testing.assert_allclose(nn.moe(nn.pack_moe(p["moe"]), y1, alpha), nn.moe(p["moe"], y1, alpha),
                               rtol=1e-5, atol=1e-6)
    # and the blend really depends on the gate (not a trivially equal pair of zeros)
    assert float(jnp.abs(nn.moe(p["moe"], y1, alpha) - nn.moe(p["moe"], y1, alpha[:, ::-1])).max()) > 1e-3


@pytest.mark.parametrize("switch", [None, "encoder_lstm", "phase_moe", "bidirectional"])
def test_deferred_weight_gradients_equal_autodiff(setup, switch):
    """Taps + one matmul after the scan give the same gradient as autodiff through the scan."""
    data, state, batch = setup
    cfg = CFG if switch is None else dataclasses.replace(CFG, model=dataclasses.replace(CFG.model, **{switch: False}))
    params = jax.tree.map(jnp.asarray, _ablated_params(state["params"], switch)) if switch else state["params"]
    args = (state["disc"], cfg, state["stats"], batch, jax.random.key(5), data.parents, MAXLEN)
    plain = jax.grad(lambda p: T.generator_loss(p, *args)[0])(params)
    taps = D.make_taps(params, cfg.model, batch["q"].shape[0], M.num_scan_steps(cfg.model, MAXLEN))
    (_, (_, _, recs)), (g, g_taps) = jax.value_and_grad(
        lambda p, t: T.generator_loss(p, *args, t), argnums=(0, 1), has_aux=True)(params, taps)
    assert recs, "no matmul inputs were recorded"
    total = D.add_deferred_weight_grads(g, recs, g_taps)
    lstm_wx = total["fwd"]["dec"]["lstm"]["wx"]
    assert float(jnp.abs(lstm_wx).max()) > 0 and float(jnp.abs(g["fwd"]["dec"]["lstm"]["wx"]).max()) == 0
    for (path, a), b in zip(jax.tree_util.tree_leaves_with_path(plain), jax.tree.leaves(total)):
        np.testing.assert_allclose(b, a, rtol=2e-4, atol=2e-6, err_msg=jax.tree_util.keystr(path))
