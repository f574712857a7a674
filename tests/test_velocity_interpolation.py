"""The velocity-continuing interpolation (``baselines.velocity_interpolation``) against an independent cubic
Hermite spline (scipy), and the S-CVAE's ``model.base_velocity`` switch built on it (real CMU windows)."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

from inbetween_jax.baselines import interpolate_transition, velocity_interpolate_transition
from inbetween_jax.data import load_dataset
from inbetween_jax.geometry import quat_from_axis_angle
from inbetween_jax.models.scvae import model as M
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.models.scvae.features import TrainData, compute_stats

MAXLEN = 11


def _one_axis_clip(angles, roots, axis=(0.3, 0.8, -0.52)):
    """(T,) angles about one axis for 2 joints (the second at half speed) and (T, 3) roots -> (1, T, 2, 4), (1, T, 3)."""
    ax = np.asarray(axis) / np.linalg.norm(axis)
    a = np.stack([angles, 0.5 * angles], -1)                                      # (T, 2)
    q = np.asarray(quat_from_axis_angle(np.broadcast_to(ax, a.shape + (3,)), a), np.float64)
    return q[None], np.asarray(roots, np.float64)[None]


@pytest.mark.parametrize("n_trans", [5, 17])
def test_matches_an_independent_cubic_hermite_spline(n_trans):
    """Rotations about one fixed axis and the root, each a 1-D curve: the path equals scipy's cubic Hermite spline
    through the keyframes with the last past frame's velocity as start tangent and the chord slope at the end."""
    rng = np.random.default_rng(0)
    n_past, t_total = 3, 3 + n_trans + 2
    angles = np.cumsum(rng.uniform(-0.15, 0.25, t_total))
    roots = np.cumsum(rng.normal(0, 2.0, (t_total, 3)), 0)
    q, r = _one_axis_clip(angles, roots)
    pq, pr = velocity_interpolate_transition(q, r, n_past, n_trans)
    k0, k1, length = n_past - 1, n_past + n_trans, n_trans + 1
    t = np.arange(1, length)
    for sig, got in ((roots, pr[0]), (angles, None)):
        chord = (sig[k1] - sig[k0]) / length
        spline = CubicHermiteSpline([0, length], [sig[k0], sig[k1]], [sig[k0] - sig[k0 - 1], chord])
        want = spline(t)
        if got is None:   # angle of joint 0 about the axis, from the predicted quaternion
            qq = pq[0, :, 0] * np.sign(pq[0, :, 0, :1])
            got = 2 * np.arctan2(np.linalg.norm(qq[:, 1:], axis=-1), qq[:, 0])
            want = np.abs(want)
        np.testing.assert_allclose(got, want, atol=2e-4)


def test_uniform_motion_is_plain_interpolation_and_velocity_is_continuous():
    """Motion already moving along the chord at constant speed: nothing to add.  Otherwise the first step of the
    path repeats the last past step (velocity continuous), unlike Slerp / lerp."""
    n_past, n_trans = 4, 9
    t_total = n_past + n_trans + 1
    angles = 0.05 * np.arange(t_total)
    roots = np.stack([3.0 * np.arange(t_total), np.zeros(t_total), -np.arange(t_total)], -1)
    q, r = _one_axis_clip(angles, roots)
    vq, vr = velocity_interpolate_transition(q, r, n_past, n_trans)
    sq, sr = interpolate_transition(q, r, n_past, n_trans)
    np.testing.assert_allclose(vr, sr, atol=1e-5)
    np.testing.assert_allclose(np.abs(np.sum(vq * np.asarray(sq), -1)), 1.0, atol=1e-6)
    roots2 = roots.copy()
    roots2[n_past:] += np.array([40.0, 0.0, 0.0])                                  # a jump the chord must absorb
    _, vr2 = velocity_interpolate_transition(q, roots2[None], n_past, n_trans)
    _, sr2 = interpolate_transition(q, roots2[None], n_past, n_trans)
    last_step = roots2[n_past - 1] - roots2[n_past - 2]
    first_v, first_s = vr2[0, 0] - roots2[n_past - 1], np.asarray(sr2)[0, 0] - roots2[n_past - 1]
    assert np.linalg.norm(first_v - last_step) < 0.3 * np.linalg.norm(first_s - last_step)


def test_needs_two_past_frames():
    q, r = _one_axis_clip(np.zeros(8), np.zeros((8, 3)))
    with pytest.raises(ValueError, match="two past frames"):
        velocity_interpolate_transition(q, r, 1, 4)


def test_base_velocity_switch_untrained_model_is_exactly_the_velocity_path():
    """Real windows: the untrained residual S-CVAE with ``model.base_velocity`` reproduces the baseline through
    the stitch; without the previous frame (one keyframe) it falls back to Slerp."""
    w = load_dataset(None, "train")
    data = TrainData.from_windows(w.take(slice(0, 8)))
    stats = jax.tree.map(jnp.asarray, compute_stats(w))
    batch = jax.tree.map(jnp.asarray, T.make_batch(data, np.arange(4), np.array([1, 3, 10, 20]), MAXLEN, MAXLEN,
                                                   velocity=True))
    tiny = get_config("tiny")
    cfg = dataclasses.replace(tiny, model=dataclasses.replace(tiny.model, residual=True, decoder_target=True,
                                                              start_velocity=True, base_velocity=True))
    params = M.init_params(jax.random.key(0), cfg.model, data.q.shape[2])
    start, target, _, _ = T.split_batch(batch)
    out = M.rollout(params, cfg.model, stats, start, target, MAXLEN, jax.random.key(3), MAXLEN)["out"]
    idx, starts = np.arange(4), np.array([1, 3, 10, 20])
    frames = starts[:, None] + np.arange(-1, MAXLEN + 1)[None]                    # previous, start .. target
    wq, wr = velocity_interpolate_transition(data.q[idx[:, None], frames], data.r[idx[:, None], frames], 2,
                                             MAXLEN - 1)
    got_q = np.asarray(out["q"][:, 1:MAXLEN])
    np.testing.assert_allclose(np.abs(np.sum(got_q * wq, -1)), 1.0, atol=1e-5)
    np.testing.assert_allclose(np.asarray(out["r"][:, 1:MAXLEN]), wr, atol=1e-3)
    sq, sr = interpolate_transition(data.q[idx[:, None], frames], data.r[idx[:, None], frames], 2, MAXLEN - 1)
    assert np.abs(np.asarray(out["r"][:, 1:MAXLEN]) - sr).max() > 0.1              # the switch changed the path
    plain = {k: v for k, v in start.items() if k not in ("qp", "v")}
    out1 = M.rollout(params, cfg.model, stats, plain, target, MAXLEN, jax.random.key(3), MAXLEN)["out"]
    np.testing.assert_allclose(np.asarray(out1["r"][:, 1:MAXLEN]), sr, atol=1e-3)


def test_official_rows_give_the_velocity_model_its_past_frame():
    """The bench's official-protocol rows (10 past frames) of an untrained ``improved-velocity``-style model equal
    the velocity baseline's row: the protocol hands the model the frame before the start keyframe."""
    from types import SimpleNamespace

    from inbetween_jax.data import l2p_stats
    from inbetween_jax.models.scvae.bench import VELOCITY_BASELINE, official_rows
    bench = load_dataset(None, "benchmark").take(slice(0, 6))
    w = load_dataset(None, "train")
    tiny = get_config("tiny")
    cfg = dataclasses.replace(tiny, model=dataclasses.replace(tiny.model, residual=True, decoder_target=True,
                                                              start_velocity=True, base_velocity=True))
    state = {"params": M.init_params(jax.random.key(0), cfg.model, w.local_quats.shape[2]),
             "stats": jax.tree.map(jnp.asarray, compute_stats(w))}
    x_mean, x_std = l2p_stats(w.global_pose()[1])
    rows = official_rows(SimpleNamespace(cfg=cfg, state=state), bench, x_mean, x_std, "model")
    by = {(r["method"], r["frames"]): r for r in rows}
    assert {m for m, _ in by} == {"Slerp", VELOCITY_BASELINE, "model"}
    for (m, n), r in by.items():
        if m == "model":
            np.testing.assert_allclose(r["L2P"], by[(VELOCITY_BASELINE, n)]["L2P"], rtol=1e-3)
            assert abs(r["L2P"] - by[("Slerp", n)]["L2P"]) > 1e-3
