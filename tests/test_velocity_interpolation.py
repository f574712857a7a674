"""The velocity-continuing interpolation (``baselines.velocity_interpolation``) against an independent cubic
Hermite spline (scipy), and the S-CVAE's ``model.base_velocity`` switch built on it (real CMU windows)."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

from inbetween_jax.baselines import interpolate_transition, velocity_interpolate_transition
from inbetween_jax.baselines.velocity_interpolation import hermite_weights
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


def test_damping_fades_the_offset_but_keeps_the_start_velocity():
    """``damping``: the offset from Slerp / lerp is the undamped one times exp(-damping * t) (root and joints), so
    the path still leaves the keyframe along the motion (same tangent at t = 0) and still reaches the target."""
    rng = np.random.default_rng(1)
    n_past, n_trans = 3, 20
    angles = np.cumsum(rng.uniform(-0.15, 0.25, n_past + n_trans + 1))
    roots = np.cumsum(rng.normal(0, 2.0, (n_past + n_trans + 1, 3)), 0)
    q, r = _one_axis_clip(angles, roots)
    _, sr = interpolate_transition(q, r, n_past, n_trans)
    (uq, ur), (dq, dr) = (velocity_interpolate_transition(q, r, n_past, n_trans, d) for d in (0.0, 0.1))
    fade = np.exp(-0.1 * np.arange(1, n_trans + 1))[:, None]
    np.testing.assert_allclose(dr[0] - sr[0], (ur[0] - sr[0]) * fade, atol=1e-4)
    assert np.abs(dr[0] - sr[0]).max() < np.abs(ur[0] - sr[0]).max()
    np.testing.assert_allclose(np.asarray(hermite_weights(21, 21, 0.1))[[0, 21]], 0.0, atol=1e-7)
    g = np.asarray(hermite_weights(21, 21, 0.1))
    assert abs(g[1] - np.asarray(hermite_weights(21, 21))[1]) < 0.11 * g[1]      # slope ~1 at the keyframe


def test_needs_two_past_frames():
    q, r = _one_axis_clip(np.zeros(8), np.zeros((8, 3)))
    with pytest.raises(ValueError, match="two past frames"):
        velocity_interpolate_transition(q, r, 1, 4)


@pytest.mark.parametrize("damping", [0.0, 0.1])
def test_base_velocity_switch_untrained_model_is_exactly_the_velocity_path(damping):
    """Real windows: the untrained residual S-CVAE with ``model.base_velocity`` (and ``base_damping``) reproduces
    the baseline through the stitch; without the previous frame (one keyframe) it falls back to Slerp."""
    w = load_dataset(None, "train")
    data = TrainData.from_windows(w.take(slice(0, 8)))
    batch = jax.tree.map(jnp.asarray, T.make_batch(data, np.arange(4), np.array([1, 3, 10, 20]), MAXLEN, MAXLEN,
                                                   velocity=True))
    cfg, state = _untrained_velocity_model(w, damping)
    params, stats = state["params"], state["stats"]
    start, target, _, _ = T.split_batch(batch)
    out = M.rollout(params, cfg.model, stats, start, target, MAXLEN, jax.random.key(3), MAXLEN)["out"]
    idx, starts = np.arange(4), np.array([1, 3, 10, 20])
    frames = starts[:, None] + np.arange(-1, MAXLEN + 1)[None]                    # previous, start .. target
    wq, wr = velocity_interpolate_transition(data.q[idx[:, None], frames], data.r[idx[:, None], frames], 2,
                                             MAXLEN - 1, damping)
    got_q = np.asarray(out["q"][:, 1:MAXLEN])
    np.testing.assert_allclose(np.abs(np.sum(got_q * wq, -1)), 1.0, atol=1e-5)
    np.testing.assert_allclose(np.asarray(out["r"][:, 1:MAXLEN]), wr, atol=1e-3)
    sq, sr = interpolate_transition(data.q[idx[:, None], frames], data.r[idx[:, None], frames], 2, MAXLEN - 1)
    assert np.abs(np.asarray(out["r"][:, 1:MAXLEN]) - sr).max() > 0.1              # the switch changed the path
    plain = {k: v for k, v in start.items() if k not in ("qp", "v")}
    out1 = M.rollout(params, cfg.model, stats, plain, target, MAXLEN, jax.random.key(3), MAXLEN)["out"]
    np.testing.assert_allclose(np.asarray(out1["r"][:, 1:MAXLEN]), sr, atol=1e-3)


def _untrained_velocity_model(w, damping: float = 0.0):
    """(tiny config with the residual velocity switches, untrained state) for the windows ``w``."""
    tiny = get_config("tiny")
    cfg = dataclasses.replace(tiny, model=dataclasses.replace(tiny.model, residual=True, decoder_target=True,
                                                              start_velocity=True, base_velocity=True,
                                                              base_damping=damping))
    state = {"params": M.init_params(jax.random.key(0), cfg.model, w.local_quats.shape[2]),
             "stats": jax.tree.map(jnp.asarray, compute_stats(w))}
    return cfg, state


def test_official_rows_give_the_velocity_model_its_past_frame():
    """The bench's official-protocol rows (10 past frames) of an untrained ``improved-velocity``-style model (with
    ``base_damping``) equal the velocity baseline's row with the model's damping: the protocol hands the model the
    frame before the start keyframe."""
    from types import SimpleNamespace

    from inbetween_jax.data import l2p_stats
    from inbetween_jax.models.scvae.bench import official_rows, velocity_baseline_name
    bench = load_dataset(None, "benchmark").take(slice(0, 6))
    w = load_dataset(None, "train")
    cfg, state = _untrained_velocity_model(w, 0.1)
    x_mean, x_std = l2p_stats(w.global_pose()[1])
    rows = official_rows(SimpleNamespace(cfg=cfg, state=state, bank=None), bench, x_mean, x_std, "model")
    by = {(r["method"], r["frames"]): r for r in rows}
    base = velocity_baseline_name(cfg.model)
    assert {m for m, _ in by} == {"Slerp", base, "model"} and "damped 0.1 / frame" in base
    for (m, n), r in by.items():
        if m == "model":
            np.testing.assert_allclose(r["L2P"], by[(base, n)]["L2P"], rtol=1e-3)
            assert abs(r["L2P"] - by[("Slerp", n)]["L2P"]) > 1e-3


@pytest.mark.parametrize("past", [True, False])
def test_infill_continues_the_frame_before_the_start_keyframe(past):
    """``inbetween infill`` on a real CMU clip in its own world space (any heading, away from the origin): an
    untrained velocity model given the frame before the start keyframe returns the velocity path computed directly
    in world space (the canonical turn and its inverse are exact); without that frame, Slerp / lerp."""
    from inbetween_jax.data import load_motions
    from inbetween_jax.models.scvae.infer import Trained, infill_between
    m = load_motions(None, "train")[0]
    sf, frames = 20, 9
    ef = sf + frames + 1
    w = load_dataset(None, "train")
    cfg, state = _untrained_velocity_model(w)
    trained = Trained(cfg, state, 0, m.skeleton, {"num_joints": w.local_quats.shape[2]})
    start = {"q": m.local_quats[sf], "r": m.root_pos[sf], "c": np.zeros(4, np.float32)}
    end = {"q": m.local_quats[ef], "r": m.root_pos[ef], "c": np.zeros(4, np.float32)}
    if past:
        start.update(qp=m.local_quats[sf - 1], rp=m.root_pos[sf - 1])
    out = infill_between(trained, m.skeleton, start, end, frames, 1)
    clip_q, clip_r = m.local_quats[None, sf - 1:ef + 1], m.root_pos[None, sf - 1:ef + 1]
    path = velocity_interpolate_transition if past else interpolate_transition
    wq, wr = path(clip_q, clip_r, 2, frames)
    np.testing.assert_allclose(np.abs(np.sum(out["q"][0, 1:-1] * np.asarray(wq[0]), -1)), 1.0, atol=2e-5)
    np.testing.assert_allclose(out["r"][0, 1:-1], np.asarray(wr[0]), atol=2e-3 * np.abs(clip_r).max())
    sq, sr = interpolate_transition(clip_q, clip_r, 2, frames)
    moved = np.abs(out["r"][0, 1:-1] - np.asarray(sr[0])).max()
    assert past == (moved > 1e-2 * np.abs(clip_r[0, 1] - clip_r[0, 0]).max())
