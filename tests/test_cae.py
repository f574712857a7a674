"""Convolutional inpainting AE: masks, curriculum, padding, shapes, representation, inference helpers, metrics."""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

import jax
import jax.numpy as jnp

from inbetween_jax.baselines import linear_fill
from inbetween_jax.data import load_motions
from inbetween_jax.geometry import bone_lengths, forward_kinematics
from inbetween_jax.geometry.fit import fit_rotations
from inbetween_jax.geometry.heading import rotate_about_up
from inbetween_jax.models.cae import features as cf
from inbetween_jax.models.cae import masks as cm
from inbetween_jax.models.cae import model as cae
from inbetween_jax.models.cae.config import get_config
from inbetween_jax.models.cae.infer import slerp_gaps
from inbetween_jax.train import apply_overrides


def _cfg(variant="cae", channels="2,2,4,4,4", hidden=4, width=5):
    return apply_overrides(get_config("tiny"), [f"model.variant={variant}", f"model.channels={channels}",
                                                f"model.holden_hidden={hidden}", f"model.holden_width={width}"])


@pytest.fixture(scope="module")
def motion():
    """A real clip: the longest embedded CMU test motion (600 frames, 21 joints, 30 Hz)."""
    return max(load_motions("embedded", "test"), key=lambda m: m.num_frames)


# ----------------------------------------------------------------------------- masks / curriculum
def test_gap_mask_statistics():
    mask, lam = cm.gap_mask(jax.random.key(0), 4000, 240, 60.0, 10.0)
    mask, lam = np.asarray(mask), np.asarray(lam)
    missing = 1 - mask
    assert np.array_equal(missing.sum(1), lam)                        # mask length = sampled length
    # one contiguous block per clip
    assert np.all(np.abs(np.diff(missing, axis=1)).sum(1) <= 2)
    assert abs(lam.mean() - 60) < 0.6 and abs(lam.std() - 10) < 0.6
    start = missing.argmax(1)
    assert start.min() == 0 or start.min() < 5
    assert np.all(start + lam <= 240)
    # start uniform on [0, T - lam]: its normalised position has mean 1/2 and variance 1/12
    u = start / (240 - lam)
    assert abs(u.mean() - 0.5) < 0.02 and abs(u.var() - 1 / 12) < 0.01
    # clipping keeps degenerate draws inside [1, T - 1]
    _, lam2 = cm.gap_mask(jax.random.key(1), 2000, 50, 10.0, 40.0)
    assert int(lam2.min()) >= 1 and int(lam2.max()) <= 49


def test_joint_mask_and_training_mask():
    jm = np.asarray(cm.joint_row_mask(jax.random.key(0), 3000, 22, 3))
    removed = (1 - jm).sum(1)
    assert set(np.unique(removed)) == {1, 2, 3}
    assert np.all(np.abs(np.bincount(removed.astype(int))[1:] / 3000 - 1 / 3) < 0.04)
    assert np.all(jm[:, 0] == 1)                                      # the root is never removed
    m = np.asarray(cm.training_mask(jax.random.key(3), 2000, 22, 240, 60.0, 20.0, 0.3, 3))
    assert m.shape == (2000, 69, 240)
    joint_type = (m.max(axis=1) == 1).all(axis=1)                       # no whole column removed
    assert abs(joint_type.mean() - 0.3) < 0.04
    # joint-type masks remove whole rows in triples; velocity rows stay
    r = m[joint_type]
    assert np.all(r[:, 66:] == 1) and np.all((r.min(2) == r.max(2)))
    col = m[~joint_type]
    assert np.all(col.min(axis=1) == col.max(axis=1))                 # whole columns


def test_curriculum_schedule():
    mus = [cm.curriculum_mu(e) for e in range(70)]
    assert mus[0] == mus[4] == 10 and mus[5] == 20 and mus[9] == 20 and mus[10] == 30
    assert mus[54] == 110 and mus[55] == 120 and mus[69] == 120
    assert all(b - a in (0, 10) for a, b in zip(mus, mus[1:]))
    from inbetween_jax.models.cae.train import epoch_mu
    cfg = get_config("tiny")
    assert epoch_mu(cfg, 7) == 20
    assert epoch_mu(apply_overrides(cfg, ["data.mask.curriculum=false"]), 100) == 60


# ----------------------------------------------------------------------------- padding / shapes
def test_level_sizes_and_pooling_pad_odd_lengths():
    assert cae.level_sizes(69, 240) == [(69, 240), (35, 120), (18, 60), (9, 30), (5, 15), (3, 8)]
    for t in range(37, 501):                  # every length: each level is ceil(previous / 2)
        sizes = cae.level_sizes(69, t)
        assert all(w2 == -(-w1 // 2) for (_, w1), (_, w2) in zip(sizes, sizes[1:]))
    x = np.random.default_rng(0).normal(size=(2, 5, 7, 3)).astype(np.float32)
    y = np.asarray(cae.max_pool_ceil(jnp.asarray(x)))
    assert y.shape == (2, 3, 4, 3)
    pad = np.pad(x, ((0, 0), (0, 1), (0, 1), (0, 0)), constant_values=-np.inf)
    ref = pad.reshape(2, 3, 2, 4, 2, 3).max(axis=(2, 4))
    np.testing.assert_array_equal(y, ref)                              # -inf pad never wins
    assert np.all(np.isfinite(y))
    z = np.asarray(cae.upsample_zeros(jnp.asarray(y)))
    assert z.shape == (2, 6, 8, 3) and np.array_equal(z[:, ::2, ::2], y) and z[:, 1::2].sum() == 0


@pytest.mark.parametrize("variant", ["cae", "vanilla", "holden1d"])
def test_output_shape_equals_input(variant):
    cfg = _cfg(variant)
    params = cae.init_params(jax.random.key(0), cfg, 69)
    assert all(isinstance(v, (dict, list)) for v in params.values())  # plain pytree, no nnx state
    apply = jax.jit(lambda p, x: cae.apply(p, x, cfg))
    for t in (37, 64, 241, 499):
        y = apply(params, jnp.zeros((1, 69, t)))
        assert y.shape == (1, 69, t), (variant, t)
        assert bool(jnp.all(jnp.isfinite(y)))
    if variant == "cae":
        z, _ = cae.encode(params, jnp.zeros((1, 69, 240)), cfg)
        assert z.shape == (1, 3, 8, 4)                                 # paper: 3 x 8 latent for 69 x 240


@pytest.mark.slow
def test_output_shape_all_lengths_traced():
    """Every length 37..500 through the CAE, shape-only (traced, not compiled)."""
    cfg = _cfg("cae", "1,1,1,1,1")
    params = cae.param_shapes(cfg, 69)
    for t in range(37, 501):
        assert jax.eval_shape(lambda p, x: cae.apply(p, x, cfg), params,
                              jax.ShapeDtypeStruct((1, 69, t), jnp.float32)).shape == (1, 69, t)


@pytest.mark.parametrize("up_h", [True, False])
def test_conv_upsampled_equals_conv_over_zero_dilated_input(up_h):
    """The phase-split transposed conv against its definition (a SAME conv over the zero-inserted input):
    values and both gradients, odd and even sizes."""
    rng = np.random.default_rng(0)
    for shape in ((2, 5, 7, 3), (1, 4, 6, 2), (2, 1, 3, 3)):
        z = jnp.asarray(rng.normal(size=shape), jnp.float32)
        w = jnp.asarray(rng.normal(size=(3, 3, shape[-1], 4)), jnp.float32)
        ref = lambda z, w: jnp.sin(cae.conv_same(cae.upsample_zeros(z, up_h), w))
        new = lambda z, w: jnp.sin(cae.conv_upsampled(z, w, up_h))
        np.testing.assert_allclose(new(z, w), ref(z, w), rtol=1e-5, atol=1e-5)
        assert new(z, w).shape == (shape[0], shape[1] * (2 if up_h else 1), shape[2] * 2, 4)
        for a, b in zip(jax.grad(lambda *a: new(*a).sum(), (0, 1))(z, w),
                        jax.grad(lambda *a: ref(*a).sum(), (0, 1))(z, w)):
            np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-4)


def test_xavier_init_scale():
    layer = cae.init_params(jax.random.key(0), _cfg("cae", "128,1,1,1,1"), 69)["enc"][0][1]
    w = layer["w"]
    assert w.shape == (3, 3, 128, 128)
    bound = np.sqrt(6.0 / (9 * 128 + 9 * 128))                         # Glorot uniform, fan = 3*3*C
    assert float(jnp.abs(w).max()) <= bound and float(jnp.abs(w).max()) > 0.9 * bound
    assert float(jnp.abs(layer["b"]).max()) == 0.0


# ----------------------------------------------------------------------------- representation
def test_representation_round_trip_on_real_motion(motion):
    f = cf.body_frame_features(motion)
    j = motion.skeleton.num_joints
    assert f.features.shape == (motion.num_frames, 3 * j + 3)
    local, vel = cf.split_features(f.features, j)
    np.testing.assert_allclose(local[:, 0, [0, 2]], 0.0, atol=1e-3)   # root at the body-frame origin
    g = cf.features_to_global(f.features, j, f.ref0, f.yaw0)
    _, gp = forward_kinematics(motion.local_quats, motion.local_pos, motion.skeleton.parents)
    assert np.abs(g - gp).max() < 0.05                                 # cm, after integrating 600 frames


def test_facing_forward_on_walking_clips():
    """Subjects 07 / 08 of the embedded set walk: in the body frame they move along +Z, not sideways."""
    walks = [m for m in load_motions("embedded", "train") if m.source.split("/")[-1].startswith(("07_", "08_"))]
    vel = np.concatenate([cf.split_features(cf.body_frame_features(m).features, m.skeleton.num_joints)[1]
                          for m in walks])
    assert vel[:, 1].mean() > 1.0 and vel[:, 1].mean() > 5 * abs(vel[:, 0].mean())


def test_yaw_rotate_and_integrate_root():
    np.testing.assert_allclose(rotate_about_up(np.array([0.0, 1.0]), np.pi / 2), [1.0, 0.0], atol=1e-12)
    yaw = np.linspace(0, 3, 50)
    ref = np.cumsum(np.stack([np.sin(yaw), np.cos(yaw)], -1), 0)
    vel = np.zeros((50, 3))
    vel[1:, :2] = rotate_about_up(ref[1:] - ref[:-1], -yaw[:-1])
    vel[1:, 2] = yaw[1:] - yaw[:-1]
    r2, y2 = cf.integrate_root(vel, ref[0], yaw[0])
    np.testing.assert_allclose(r2, ref, atol=1e-9)
    np.testing.assert_allclose(y2, yaw, atol=1e-12)


# ----------------------------------------------------------------------------- inference helpers
def test_gap_helpers_and_linear_fill():
    fm = cm.gap_frames(100, [(10, 20), (50, 90)])
    assert cm.gap_ranges(fm) == [(10, 20), (50, 90)]
    with pytest.raises(ValueError):
        cm.gap_frames(10, [(5, 11)])
    t = np.arange(100, dtype=np.float32)
    x = np.stack([2 * t + 1, -t]) [None]                               # (1, 2, 100) linear rows
    m = np.broadcast_to(fm, x.shape)
    np.testing.assert_allclose(linear_fill(x * m, m), x, rtol=1e-6)
    m2 = np.ones_like(x)
    m2[0, 1] = 0                                                       # a row with nothing known -> 0
    assert np.all(linear_fill(x, m2)[0, 1] == 0)
    dm = cm.dropout_mask(np.random.default_rng(0), (4, 500), 22, 0.3)
    assert dm.shape == (4, 69, 500) and abs(1 - dm[:, :66].mean() - 0.3) < 0.01 and np.all(dm[:, 66:] == 1)
    jm = cm.joints_mask(30, 22, [3, 5])
    assert jm[9:12].sum() == 0 and jm[15:18].sum() == 0 and jm.sum() == (69 - 6) * 30


def test_fit_rotations_points_bones(motion):
    m = motion.slice(0, 120)
    parents = m.skeleton.parents
    _, gp = forward_kinematics(m.local_quats, m.local_pos, parents)
    fm = cm.gap_frames(120, [(40, 80)])
    ref_q = slerp_gaps(m.local_quats, fm)
    np.testing.assert_allclose(ref_q[fm > 0.5], m.local_quats[fm > 0.5])   # known frames untouched
    before = forward_kinematics(ref_q, m.local_pos, parents)[1]
    lq, lp = fit_rotations(gp, ref_q, m.local_pos, parents, fm < 0.5)
    after = forward_kinematics(lq, lp, parents)[1]
    gap = fm < 0.5
    e_before = np.linalg.norm(before - gp, axis=-1)[gap].mean()
    e_after = np.linalg.norm(after - gp, axis=-1)[gap].mean()
    assert e_after < 0.25 * e_before and e_after < 2.0
    np.testing.assert_allclose(after[~gap], gp[~gap], atol=1e-6)


# ----------------------------------------------------------------------------- errors / bone lengths
def test_position_error_and_bone_spread_match_numpy(motion):
    """Body-frame joint errors and bone-length spread of real clips against plain NumPy references."""
    from inbetween_jax.data.features import Normalizer
    from inbetween_jax.evaluation.infilling import position_error, test_clips
    from inbetween_jax.metrics import bone_length_spread
    f = cf.body_frame_features(motion).features
    norm = Normalizer.fit(f, eps=1e-3)
    j = motion.skeleton.num_joints
    x = test_clips([motion], norm, length=120, stride=60)                # (9, 66, 120) real clips
    assert x.shape == (9, 3 * j + 3, 120)
    y = x + np.random.default_rng(0).normal(0, 0.1, x.shape).astype(np.float32)
    frames = np.zeros(x.shape[::2], np.float32)
    frames[:, 30:70] = 1
    pos = lambda c: np.swapaxes(norm.inverse(np.swapaxes(c.astype(np.float64), 1, 2)), 1, 2)[:, :3 * j]
    err = np.linalg.norm((pos(y) - pos(x)).reshape(9, j, 3, 120), axis=2)          # (N, J, T)
    ref = err[:, :, 30:70]
    mean, std = position_error(y, x, norm, j, frames)
    np.testing.assert_allclose([mean, std], [ref.mean(), ref.std()], rtol=1e-5)
    mean_all, _ = position_error(y, x, norm, j)
    np.testing.assert_allclose(mean_all, err.mean(), rtol=1e-5)
    pp, gg = cf.body_positions(y, norm, j), cf.body_positions(x, norm, j)
    pb = bone_lengths(pp, motion.skeleton.parents).reshape(-1, j - 1)
    gb = bone_lengths(gg, motion.skeleton.parents).reshape(-1, j - 1)
    b = bone_length_spread(pp, gg, tuple(motion.skeleton.parents))
    np.testing.assert_allclose(float(b["median_dev"]), np.mean(np.abs(np.median(pb, 0) - np.median(gb, 0))),
                               rtol=1e-4)
    np.testing.assert_allclose(float(b["std"]), np.mean(pb.std(0)), rtol=1e-4)
    np.testing.assert_allclose(float(b["gt_std"]), np.mean(gb.std(0)), atol=1e-4)   # ~0: FK keeps the bones
    np.testing.assert_allclose(float(b["iqr"]), np.mean(np.subtract(*np.percentile(pb, [75, 25], 0))), rtol=1e-4)
    assert float(b["gt_std"]) < 1e-3 and float(b["std"]) > 0.1       # noise spreads the bone lengths


# ----------------------------------------------------------------------------- departures from the paper (switches)
def _clips(motion, n=2, length=240):
    """(n, D, length) normalised clip images of a real motion."""
    f = cf.body_frame_features(motion).features
    f = (f - f.mean(0)) / (f.std(0) + 1e-3)
    return np.stack([f[i * 120:i * 120 + length].T for i in range(n)]).astype(np.float32)


def _real_masks(x, j):
    """A centred 60-frame gap, a clip with 2 joints missing and 20 % joint dropout on top."""
    n, _, t = x.shape
    m = cm.frame_mask_image(np.broadcast_to(cm.gap_frames(t, [(90, 150)]), (n, t)), j)
    m[1] = cm.joints_mask(t, j, [4, 9])
    return m * cm.dropout_mask(np.random.default_rng(0), (n, t), j, 0.2)


def test_linear_prefill_matches_baseline(motion):
    x = _clips(motion)
    m = _real_masks(x, motion.skeleton.num_joints)
    got = np.asarray(cm.linear_prefill(x * m, m))
    np.testing.assert_allclose(got, linear_fill(x * m, m), atol=1e-5)
    assert np.array_equal(got[m > 0.5], x[m > 0.5])                     # known entries bit for bit
    m2 = m.copy()
    m2[0, 3] = 0                                                        # a row with nothing known -> 0
    assert np.all(np.asarray(cm.linear_prefill(x * m2, m2))[0, 3] == 0)


@pytest.mark.parametrize("variant", ["cae", "vanilla", "holden1d"])
def test_residual_untrained_is_linear_fill(motion, variant):
    """model.residual: the untrained model returns linear fill in the gap and the input elsewhere, exactly;
    switched off, the same init returns something else."""
    x = _clips(motion)
    j = motion.skeleton.num_joints
    m = _real_masks(x, j)
    cfg = apply_overrides(_cfg(variant), ["model.residual=true"])
    p = cae.init_params(jax.random.key(0), cfg, x.shape[1])
    y = np.asarray(cae.apply(p, jnp.asarray(x * m), cfg, jnp.asarray(m)))
    assert np.array_equal(y, np.asarray(cm.linear_prefill(x * m, m)))
    assert np.array_equal(y[m > 0.5], x[m > 0.5])
    np.testing.assert_allclose(y, linear_fill(x * m, m), atol=1e-5)
    plain = _cfg(variant)
    y0 = np.asarray(cae.apply(cae.init_params(jax.random.key(0), plain, x.shape[1]), jnp.asarray(x * m), plain))
    assert np.abs(y0 - y)[m < 0.5].mean() > 0.1
    # a trained-looking (non-zero) output layer moves the gap but paste_known keeps the known entries
    p2 = jax.tree.map(lambda a: a + 0.01, p)
    pasted = apply_overrides(cfg, ["model.paste_known=true"])
    y2 = np.asarray(cae.apply(p2, jnp.asarray(x * m), pasted, jnp.asarray(m)))
    y3 = np.asarray(cae.apply(p2, jnp.asarray(x * m), cfg, jnp.asarray(m)))
    assert np.array_equal(y2[m > 0.5], x[m > 0.5]) and not np.array_equal(y3[m > 0.5], x[m > 0.5])
    np.testing.assert_array_equal(y2[m < 0.5], y3[m < 0.5])


def test_skips_unet_switch(motion):
    """model.skips: odd lengths keep their shape, the untrained residual model is still exactly linear fill, the
    decoder sees the encoder's features (a change in one input frame reaches the output through the skips even
    when the bottleneck is cut; without skips it does not), and other variants refuse the switch."""
    x = _clips(motion)
    m = _real_masks(x, motion.skeleton.num_joints)
    cfg = apply_overrides(_cfg("cae"), ["model.skips=true"])
    p = cae.init_params(jax.random.key(0), cfg, x.shape[1])
    assert p["dec"][-1][1]["w"].shape[2] == 2 * p["dec"][-1][0]["w"].shape[3]   # concat doubles the channels
    for t in (37, 241):
        assert cae.apply(p, jnp.zeros((1, x.shape[1], t)), cfg).shape == (1, x.shape[1], t)
    res = apply_overrides(cfg, ["model.residual=true"])
    pr = cae.init_params(jax.random.key(0), res, x.shape[1])
    y = np.asarray(cae.apply(pr, jnp.asarray(x * m), res, jnp.asarray(m)))
    assert np.array_equal(y, np.asarray(cm.linear_prefill(x * m, m)))
    # cut the bottleneck (zero the innermost decoder unit's weights): only the skips can carry the input
    cut = jax.tree.map(lambda a: a, p)
    cut["dec"][0] = jax.tree.map(jnp.zeros_like, cut["dec"][0])
    x0 = jnp.asarray(x[:1])
    x1 = x0.at[0, :, 20].add(1.0)
    change = np.abs(np.asarray(cae.apply(cut, x1, cfg) - cae.apply(cut, x0, cfg)))
    assert change.max() > 1e-3
    plain = _cfg("cae")
    pc = cae.init_params(jax.random.key(0), plain, x.shape[1])
    pc["dec"][0] = jax.tree.map(jnp.zeros_like, pc["dec"][0])
    assert float(jnp.abs(cae.apply(pc, x1, plain) - cae.apply(pc, x0, plain)).max()) == 0.0
    with pytest.raises(ValueError, match="skips"):
        cae.param_shapes(apply_overrides(_cfg("vanilla"), ["model.skips=true"]), x.shape[1])


def test_gap_weight_loss():
    from inbetween_jax.models.cae.losses import l1_loss, weighted_l1
    pred, target = jnp.zeros((1, 2, 4)), jnp.array([[[1.0, 1.0, 3.0, 3.0], [1.0, 1.0, 1.0, 1.0]]])
    mask = jnp.array([[[1.0, 1.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]]])   # two missing entries, error 3 each
    assert float(weighted_l1(pred, target, mask, 1.0)) == float(l1_loss(pred, target)) == pytest.approx(1.5)
    assert float(weighted_l1(pred, target, mask, 4.0)) == pytest.approx((6 * 1 + 2 * 4 * 3) / (6 + 2 * 4))


def test_eval_matched_gap_lengths():
    lam = np.asarray(cm.matched_gap_lengths(jax.random.key(0), 6000, (30, 60, 120), 0.25))
    which = np.select([lam <= 37.5, lam <= 75], [0, 1], 2)
    assert np.all(np.abs(np.bincount(which) / 6000 - 1 / 3) < 0.03)
    for k, c in enumerate((30, 60, 120)):
        part = lam[which == k]
        assert part.min() >= 0.75 * c - 0.5 and part.max() <= 1.25 * c + 0.5 and abs(part.mean() - c) < 0.03 * c
    # gap_mask: matched draws replace N(mu, sigma) where the flag is on
    _, l1 = cm.gap_mask(jax.random.key(1), 3000, 240, 120.0, 20.0, matched=1.0)
    _, l0 = cm.gap_mask(jax.random.key(1), 3000, 240, 120.0, 20.0, matched=0.0)
    assert abs(float(np.mean(l0)) - 120) < 2 and abs(float(np.mean(l1)) - 70) < 3
    assert cm.curriculum_end_epoch(10, 120, 10, 5) == 55 and cm.curriculum_mu(55) == 120.0
    assert cm.curriculum_end_epoch(30, 120, 30, 2) == 6 and cm.curriculum_mu(5, 30, 120, 30, 2) < 120


def test_presets_improved_matches_cpu_budget():
    from inbetween_jax.models.cae.config import DEFAULT_PRESET, PRESETS
    from inbetween_jax.train.optim import learning_rate
    cpu, imp, paper = get_config("cpu"), get_config("improved"), get_config("paper")
    assert DEFAULT_PRESET == "improved" and set(PRESETS) == {"paper", "cpu", "improved", "tiny"}
    assert (imp.model.channels, imp.train.batch_size, imp.train.num_steps, imp.data.steps_per_epoch) == \
        (cpu.model.channels, cpu.train.batch_size, cpu.train.num_steps, cpu.data.steps_per_epoch)
    for c in (cpu, paper):
        assert not (c.model.residual or c.model.paste_known or c.data.mask.eval_matched)
        assert c.loss.gap_weight == 1.0 and c.train.lr_schedule == "constant" and learning_rate(c.train) == 1e-3
    assert imp.model.residual and imp.model.paste_known and imp.data.mask.eval_matched and imp.loss.gap_weight > 1
    assert not (imp.model.skips or cpu.model.skips or paper.model.skips)       # measured, left as a switch
    sched = learning_rate(imp.train)
    assert float(sched(imp.train.warmup_steps)) == pytest.approx(1e-3)
    assert float(sched(imp.train.num_steps)) == pytest.approx(1e-3 * imp.train.lr_final)


# ----------------------------------------------------------------------------- Hermite fill (model.fill)
def _ref_tangents(row, known, p, q, limit):
    """Independent tangents at the gap ends p (before) and q (after) of one row, per frame."""
    d = (row[q] - row[p]) / (q - p)

    def one_sided(i, step):     # step -1: frames before i; +1: after i
        k1 = 0 <= i + step < len(row) and known[i + step]
        k2 = k1 and 0 <= i + 2 * step < len(row) and known[i + 2 * step]
        if k2:
            return -step * (3 * row[i] - 4 * row[i + step] + row[i + 2 * step]) / 2
        return -step * (row[i] - row[i + step]) if k1 else d

    out = []
    for m in (one_sided(p, -1), one_sided(q, 1)):
        if limit is not None:
            m = 0.0 if m * d <= 0 else np.sign(m) * min(abs(m), limit * abs(d))
        out.append(m)
    return out


def _ref_hermite(x, mask, limit=3.0, damping=0.0, edge_fade=0.0):
    """scipy.interpolate.CubicHermiteSpline per row and gap (held at the ends, 0 for an empty row).  damping:
    the line plus each tangent's departure from the secant as its own spline (zero at both ends), times
    ``exp(-damping * frames from its edge)``; edge_fade: the limited spline plus the cut part of each tangent
    (unlimited minus limited) the same way."""
    from scipy.interpolate import CubicHermiteSpline
    x, mask = np.asarray(x, np.float64), np.broadcast_to(mask, x.shape) > 0.5
    out = x.copy()
    flat, fm, fo = x.reshape(-1, x.shape[-1]), mask.reshape(-1, x.shape[-1]), out.reshape(-1, x.shape[-1])
    for r in range(len(flat)):
        k = np.flatnonzero(fm[r])
        if not len(k):
            fo[r] = 0.0
            continue
        fo[r, :k[0]], fo[r, k[-1] + 1:] = flat[r, k[0]], flat[r, k[-1]]
        for p, q in zip(k[:-1], k[1:]):
            if q - p > 1:
                m0, m1 = _ref_tangents(flat[r], fm[r], p, q, limit)
                t = np.arange(p + 1, q)
                spline = CubicHermiteSpline([p, q], [flat[r, p], flat[r, q]], [m0, m1])
                fo[r, p + 1:q] = spline(t)
                if damping or edge_fade:
                    d = (flat[r, q] - flat[r, p]) / (q - p)
                    raw0, raw1 = _ref_tangents(flat[r], fm[r], p, q, None)
                    c0, c1 = (raw0 - d, raw1 - d) if damping else (raw0 - m0, raw1 - m1)
                    k = damping or edge_fade
                    lead = CubicHermiteSpline([p, q], [0.0, 0.0], [c0, 0.0])(t) * np.exp(-k * (t - p))
                    trail = CubicHermiteSpline([p, q], [0.0, 0.0], [0.0, c1])(t) * np.exp(-k * (q - t))
                    fo[r, p + 1:q] = (flat[r, p] + d * (t - p) if damping else fo[r, p + 1:q]) + lead + trail
    return out


@pytest.mark.parametrize("limit", [3.0, None])
def test_hermite_fill_matches_scipy(limit):
    """baselines.hermite_fill (NumPy and jitted jnp) = scipy's CubicHermiteSpline with the same tangents, on
    synthetic curves with gaps of every kind: long / short, next to the clip ends, 1-known-frame sides."""
    from inbetween_jax.baselines import hermite_fill
    rng = np.random.default_rng(0)
    t = np.arange(90)
    x = np.stack([np.sin(t / 7.0 + ph) * a + 0.01 * t * c for ph, a, c in rng.normal(size=(12, 3))])[None]
    x = np.concatenate([x, rng.normal(size=x.shape).cumsum(-1)]).astype(np.float32)   # (2, 12, 90)
    fm = cm.gap_frames(90, [(0, 3), (10, 40), (42, 43), (45, 60), (61, 62), (80, 90)])
    m = np.broadcast_to(fm, x.shape).copy()
    m[1, 5] = 0                                                         # an empty row -> 0
    m[0, 2, 20:70] = 0                                                  # a row-specific longer gap
    want = _ref_hermite(x, m, limit)
    got = hermite_fill(x * m, m, limit=limit)
    assert isinstance(got, np.ndarray) and got.dtype == np.float32
    np.testing.assert_allclose(got, want, atol=2e-5, rtol=1e-5)
    assert np.array_equal(got[m > 0.5], x[m > 0.5]) and np.all(got[1, 5] == 0)
    got_j = jax.jit(functools.partial(hermite_fill, limit=limit))(jnp.asarray(x * m), jnp.asarray(m))
    np.testing.assert_allclose(np.asarray(got_j), want, atol=2e-5, rtol=1e-5)
    assert np.array_equal(np.asarray(got_j)[m > 0.5], x[m > 0.5])
    # the limiter matters: the unlimited cubic overshoots where the limited one does not
    if limit is not None:
        assert not np.allclose(hermite_fill(x * m, m, limit=None), got, atol=1e-3)


@pytest.mark.parametrize("kind", ["damping", "edge_fade"])
def test_hermite_fill_fading_tangents_match_scipy(kind):
    """hermite_fill(damping=k) (unlimited) and hermite_fill(edge_fade=k) (limited) = the scipy reference built from
    separate splines; the limits k -> 0 / large give the plain cubic / the limited fill; and where the limiter
    cuts a tangent, the edge-faded fill leaves the keyframe at the motion's own speed, the limited one does not."""
    from inbetween_jax.baselines import hermite_fill
    rng = np.random.default_rng(1)
    t = np.arange(90)
    x = np.stack([np.sin(t / 5.0 + ph) * a + 0.02 * t * c for ph, a, c in rng.normal(size=(16, 3))])[None]
    x = x.astype(np.float32)
    fm = cm.gap_frames(90, [(0, 3), (10, 40), (42, 43), (45, 60), (80, 90)])
    m = np.broadcast_to(fm, x.shape).copy()
    limit = None if kind == "damping" else 3.0
    for k in (0.1, 0.5):
        got = hermite_fill(x * m, m, limit=limit, **{kind: k})
        np.testing.assert_allclose(got, _ref_hermite(x, m, limit, **{kind: k}), atol=3e-5, rtol=1e-5)
        got_j = jax.jit(functools.partial(hermite_fill, limit=limit, **{kind: k}))(jnp.asarray(x * m), jnp.asarray(m))
        np.testing.assert_allclose(np.asarray(got_j), got, atol=2e-5)
        assert np.array_equal(got[m > 0.5], x[m > 0.5])
    if kind == "damping":
        np.testing.assert_allclose(hermite_fill(x * m, m, limit=None, damping=1e-9),
                                   hermite_fill(x * m, m, limit=None), atol=2e-5)
        return
    np.testing.assert_allclose(hermite_fill(x * m, m, edge_fade=60.0), hermite_fill(x * m, m), atol=1e-6)
    faded, limited = hermite_fill(x * m, m, edge_fade=0.3), hermite_fill(x * m, m)
    last = (3 * x[0, :, 9] - 4 * x[0, :, 8] + x[0, :, 7]) / 2          # the motion's velocity into the gap at 10
    chord = x[0, :, 40] - x[0, :, 9]
    cut = last * chord < 0                                              # rows whose tangent the limiter zeroes
    assert cut.sum() >= 3
    step_f, step_l = faded[0, cut, 10] - x[0, cut, 9], limited[0, cut, 10] - x[0, cut, 9]
    assert np.all(np.abs(step_f - last[cut]) < np.abs(step_l - last[cut]))
    assert np.all(np.sign(step_f) == np.sign(last[cut]))


def test_hermite_fill_straight_line_and_smooth_curve():
    """A straight line is reproduced exactly (any gap); a smooth curve is filled better than by a line."""
    from inbetween_jax.baselines import hermite_fill
    t = np.arange(120, dtype=np.float32)
    line = np.stack([2.0 + 0.3 * t, -1.0 - 0.05 * t, np.full_like(t, 4.0)])[None]
    fm = cm.gap_frames(120, [(5, 50), (52, 53), (70, 110)])
    for order in (1, 2):
        np.testing.assert_allclose(hermite_fill(line * fm, fm, order=order), line, rtol=2e-6, atol=1e-5)
        np.testing.assert_allclose(hermite_fill(line * fm, fm, limit=None, order=order), line, rtol=2e-6, atol=1e-5)
    curve = np.sin(t / 20.0)[None, None]
    fm2 = cm.gap_frames(120, [(40, 70)])
    err_h = np.abs(hermite_fill(curve * fm2, fm2) - curve).max()
    err_l = np.abs(linear_fill(curve * fm2, fm2) - curve).max()
    assert err_h < 0.5 * err_l


def test_residual_hermite_switch(motion):
    """model.fill=hermite: the untrained residual model (zero-initialised output conv) returns exactly the
    Hermite fill in the gap and the input elsewhere; the default stays linear (old run.json files and the
    shipped weights, which have no ``fill`` key, keep meaning linear fill)."""
    from inbetween_jax.baselines import hermite_fill
    from inbetween_jax.models.cae.config import Config
    from inbetween_jax.train.config import config_from_dict, config_to_dict
    x = _clips(motion)
    j = motion.skeleton.num_joints
    m = _real_masks(x, j)
    base = apply_overrides(_cfg("cae"), ["model.residual=true", "model.paste_known=true"])
    herm = apply_overrides(base, ["model.fill=hermite"])
    p = cae.init_params(jax.random.key(0), herm, x.shape[1])
    y = np.asarray(cae.apply(p, jnp.asarray(x * m), herm, jnp.asarray(m)))
    np.testing.assert_allclose(y, hermite_fill(x * m, m), atol=1e-5)
    assert np.array_equal(y[m > 0.5], x[m > 0.5])
    y_lin = np.asarray(cae.apply(p, jnp.asarray(x * m), base, jnp.asarray(m)))
    assert np.array_equal(y_lin, np.asarray(cm.linear_prefill(x * m, m)))
    assert np.abs(y - y_lin)[m < 0.5].mean() > 1e-3                     # the switch changes the fill
    assert get_config("cpu").model.fill == get_config("paper").model.fill == "linear"
    assert get_config("improved").model.fill == "hermite"
    old = config_to_dict(get_config("improved"))
    del old["model"]["fill"]                                            # a run.json written before the switch
    assert config_from_dict(Config, old).model.fill == "linear"
    with pytest.raises(ValueError, match="model.fill"):
        cae.init_params(jax.random.key(0), apply_overrides(base, ["model.fill=cubic"]), x.shape[1])


# ----------------------------------------------------------------------------- left-right mirror
def test_mirror_rows_match_the_mirrored_motion(motion):
    """mirror_rows / mirror_clips against an independent route: mirror the motion's world positions (x -> -x,
    left and right joints swapped by name) and compute its features from scratch (facing, body frame,
    velocities); an involution; a skeleton without left/right names is refused in one line."""
    from inbetween_jax.errors import UserError
    from inbetween_jax.data.features import Normalizer
    skel = motion.skeleton
    f = cf.body_frame_features(motion)
    twin = list(skel.mirror_map())
    assert twin != list(range(skel.num_joints)) and [twin[t] for t in twin] == list(range(skel.num_joints))
    gp = f.global_pos.astype(np.float64)[:, twin] * np.array([-1.0, 1.0, 1.0])
    want = cf.positions_to_features(gp, cf.smoothed_facing_yaw(gp, skel))
    perm, sign = cf.mirror_rows(skel)
    got = f.features[:, perm] * sign
    np.testing.assert_allclose(got, want, atol=2e-3)
    assert np.abs(got - f.features).max() > 10.0                           # a mirror moves the body (cm)
    norm = Normalizer.fit(f.features, eps=1e-3)
    x = norm(f.features).T[None]
    np.testing.assert_allclose(cf.mirror_clips(x, perm, sign, norm), norm(want).T[None], atol=5e-3)
    np.testing.assert_allclose(cf.mirror_clips(cf.mirror_clips(x, perm, sign, norm), perm, sign, norm), x, atol=1e-4)
    nameless = dataclasses.replace(skel, names=tuple(f"j{i}" for i in range(skel.num_joints)))
    with pytest.raises(UserError, match="left/right"):
        cf.mirror_rows(nameless)


def test_mirror_average_switch(motion):
    """model.mirror_average: the fill becomes mirror-equivariant (filling the mirrored clip gives the mirror of
    the fill), known entries stay pasted, and it differs from the single fill of the same parameters."""
    from inbetween_jax.data.features import Normalizer
    from inbetween_jax.models.cae.infer import TrainedCAE, fill
    x = _clips(motion)
    j = motion.skeleton.num_joints
    m = _real_masks(x, j)[:1].repeat(2, 0)
    norm = Normalizer(np.zeros(x.shape[1], np.float32), np.ones(x.shape[1], np.float32))
    cfg = apply_overrides(_cfg("cae"), ["model.residual=true", "model.paste_known=true", "model.skips=true"])
    p = jax.tree.map(lambda a: a + 0.01, cae.init_params(jax.random.key(0), cfg, x.shape[1]))
    one = TrainedCAE(p, cfg, norm, motion.skeleton, j, 0)
    avg = TrainedCAE(p, apply_overrides(cfg, ["model.mirror_average=true"]), norm, motion.skeleton, j, 0)
    perm, sign = cf.mirror_rows(motion.skeleton)
    mir = lambda a: cf.mirror_clips(a, perm, sign, norm)
    y = fill(avg, x, m)
    np.testing.assert_allclose(fill(avg, mir(x), m[:, perm]), mir(y), atol=1e-4)
    y1 = fill(one, x, m)
    assert np.abs(fill(one, mir(x), m[:, perm]) - mir(y1)).max() > 1e-2    # a single fill is not equivariant
    np.testing.assert_allclose(y, 0.5 * (y1 + mir(fill(one, mir(x), m[:, perm]))), atol=1e-5)
    np.testing.assert_allclose(y[m > 0.5], x[m > 0.5], atol=1e-5)
