"""Convolutional inpainting AE: masks, curriculum, padding, shapes, representation, inference helpers."""
from __future__ import annotations

import numpy as np
import pytest

import jax
import jax.numpy as jnp
from flax import nnx

from inbetween_jax.data import load_motions
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.models import cae
from inbetween_jax.models import cae_data as cd
from inbetween_jax.models import cae_infer as ci


@pytest.fixture(scope="module")
def motion():
    """A real clip: the longest embedded CMU test motion (600 frames, 21 joints, 30 Hz)."""
    return max(load_motions("embedded", "test"), key=lambda m: m.num_frames)


# ----------------------------------------------------------------------------- masks / curriculum
def test_gap_mask_statistics():
    mask, lam = cd.gap_mask(jax.random.key(0), 4000, 240, 60.0, 10.0)
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
    _, lam2 = cd.gap_mask(jax.random.key(1), 2000, 50, 10.0, 40.0)
    assert int(lam2.min()) >= 1 and int(lam2.max()) <= 49


def test_joint_mask_and_training_mask():
    jm = np.asarray(cd.joint_row_mask(jax.random.key(0), 3000, 22, 3))
    removed = (1 - jm).sum(1)
    assert set(np.unique(removed)) == {1, 2, 3}
    assert np.all(np.abs(np.bincount(removed.astype(int))[1:] / 3000 - 1 / 3) < 0.04)
    assert np.all(jm[:, 0] == 1)                                      # the root is never removed
    m = np.asarray(cd.training_mask(jax.random.key(3), 2000, 22, 240, 60.0, 20.0, 0.3, 3))
    assert m.shape == (2000, 69, 240)
    joint_type = (m.max(axis=1) == 1).all(axis=1)                       # no whole column removed
    assert abs(joint_type.mean() - 0.3) < 0.04
    # joint-type masks remove whole rows in triples; velocity rows stay
    r = m[joint_type]
    assert np.all(r[:, 66:] == 1) and np.all((r.min(2) == r.max(2)))
    col = m[~joint_type]
    assert np.all(col.min(axis=1) == col.max(axis=1))                 # whole columns


def test_curriculum_schedule():
    mus = [cd.curriculum_mu(e) for e in range(70)]
    assert mus[0] == mus[4] == 10 and mus[5] == 20 and mus[9] == 20 and mus[10] == 30
    assert mus[54] == 110 and mus[55] == 120 and mus[69] == 120
    assert all(b - a in (0, 10) for a, b in zip(mus, mus[1:]))
    from inbetween_jax.configs.cae import get_config
    from inbetween_jax.models.cae_train import epoch_mu
    from inbetween_jax.train import apply_overrides
    cfg = get_config("tiny")
    assert epoch_mu(cfg, 7) == 20
    assert epoch_mu(apply_overrides(cfg, ["mask.curriculum=false"]), 100) == 60


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
    model = cae.make_model(variant, 69, (2, 2, 4, 4, 4), holden_hidden=4, holden_width=5)
    gd, params = nnx.split(model)
    apply = jax.jit(lambda p, x: nnx.merge(gd, p)(x))
    for t in (37, 64, 241, 499):
        y = apply(params, jnp.zeros((1, 69, t)))
        assert y.shape == (1, 69, t), (variant, t)
        assert bool(jnp.all(jnp.isfinite(y)))
    if variant == "cae":
        z, _ = model.encode(jnp.zeros((1, 69, 240)))
        assert z.shape == (1, 3, 8, 4)                                 # paper: 3 x 8 latent for 69 x 240


@pytest.mark.slow
def test_output_shape_all_lengths_traced():
    """Every length 37..500 through the CAE, shape-only (traced, not compiled)."""
    model = cae.make_model("cae", 69, (1, 1, 1, 1, 1))
    for t in range(37, 501):
        assert jax.eval_shape(model, jax.ShapeDtypeStruct((1, 69, t), jnp.float32)).shape == (1, 69, t)


def test_conv_custom_vjp_matches_autodiff():
    rng = np.random.default_rng(0)
    x = jnp.asarray(rng.normal(size=(2, 7, 9, 3)), jnp.float32)
    for k in ((3, 3), (1, 5)):
        w = jnp.asarray(rng.normal(size=k + (3, 4)), jnp.float32)
        ref = lambda x, w: jnp.sum(jnp.sin(cae._conv(x, w)))
        new = lambda x, w: jnp.sum(jnp.sin(cae.conv_same(x, w)))
        np.testing.assert_allclose(new(x, w), ref(x, w), rtol=1e-5)
        for a, b in zip(jax.grad(new, (0, 1))(x, w), jax.grad(ref, (0, 1))(x, w)):
            np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-4)


def test_xavier_init_scale():
    conv = cae.Conv(128, 128, rngs=nnx.Rngs(0))
    w = conv.w[...]
    bound = np.sqrt(6.0 / (9 * 128 + 9 * 128))                         # Glorot uniform, fan = 3*3*C
    assert float(jnp.abs(w).max()) <= bound and float(jnp.abs(w).max()) > 0.9 * bound
    assert float(jnp.abs(conv.b[...]).max()) == 0.0


# ----------------------------------------------------------------------------- representation
def test_representation_round_trip_on_real_motion(motion):
    f = cd.motion_features(motion)
    j = motion.skeleton.num_joints
    assert f.features.shape == (motion.num_frames, 3 * j + 3)
    local, vel = cd.split_features(f.features, j)
    np.testing.assert_allclose(local[:, 0, [0, 2]], 0.0, atol=1e-3)   # root at the body-frame origin
    g = cd.features_to_global(f.features, j, f.ref0, f.yaw0)
    _, gp = forward_kinematics(motion.local_quats, motion.local_pos, motion.skeleton.parents)
    assert np.abs(g - gp).max() < 0.05                                 # cm, after integrating 600 frames


def test_facing_forward_on_walking_clips():
    """Subjects 07 / 08 of the embedded set walk: in the body frame they move along +Z, not sideways."""
    walks = [m for m in load_motions("embedded", "train") if m.source.split("/")[-1].startswith(("07_", "08_"))]
    vel = np.concatenate([cd.split_features(cd.motion_features(m).features, m.skeleton.num_joints)[1]
                          for m in walks])
    assert vel[:, 1].mean() > 1.0 and vel[:, 1].mean() > 5 * abs(vel[:, 0].mean())


def test_yaw_rotate_and_integrate_root():
    np.testing.assert_allclose(cd.yaw_rotate(np.array([0.0, 1.0]), np.pi / 2), [1.0, 0.0], atol=1e-12)
    yaw = np.linspace(0, 3, 50)
    ref = np.cumsum(np.stack([np.sin(yaw), np.cos(yaw)], -1), 0)
    vel = np.zeros((50, 3))
    vel[1:, :2] = cd.yaw_rotate(ref[1:] - ref[:-1], -yaw[:-1])
    vel[1:, 2] = yaw[1:] - yaw[:-1]
    r2, y2 = cd.integrate_root(vel, ref[0], yaw[0])
    np.testing.assert_allclose(r2, ref, atol=1e-9)
    np.testing.assert_allclose(y2, yaw, atol=1e-12)


# ----------------------------------------------------------------------------- inference helpers
def test_gap_helpers_and_linear_fill():
    fm = ci.gap_frames(100, [(10, 20), (50, 90)])
    assert ci.gap_ranges(fm) == [(10, 20), (50, 90)]
    with pytest.raises(ValueError):
        ci.gap_frames(10, [(5, 11)])
    t = np.arange(100, dtype=np.float32)
    x = np.stack([2 * t + 1, -t]) [None]                               # (1, 2, 100) linear rows
    m = np.broadcast_to(fm, x.shape)
    np.testing.assert_allclose(ci.linear_fill(x * m, m), x, rtol=1e-6)
    m2 = np.ones_like(x)
    m2[0, 1] = 0                                                       # a row with nothing known -> 0
    assert np.all(ci.linear_fill(x, m2)[0, 1] == 0)
    dm = ci.dropout_mask(np.random.default_rng(0), (4, 500), 22, 0.3)
    assert dm.shape == (4, 69, 500) and abs(1 - dm[:, :66].mean() - 0.3) < 0.01 and np.all(dm[:, 66:] == 1)
    jm = ci.joints_mask(30, 22, [3, 5])
    assert jm[9:12].sum() == 0 and jm[15:18].sum() == 0 and jm.sum() == (69 - 6) * 30


def test_fit_rotations_points_bones(motion):
    m = motion.slice(0, 120)
    parents = m.skeleton.parents
    _, gp = forward_kinematics(m.local_quats, m.local_pos, parents)
    fm = ci.gap_frames(120, [(40, 80)])
    ref_q = ci.slerp_gaps(m.local_quats, fm)
    np.testing.assert_allclose(ref_q[fm > 0.5], m.local_quats[fm > 0.5])   # known frames untouched
    before = ci.check_fk_positions(ref_q, m.local_pos, parents)
    lq, lp = ci.fit_rotations(gp, ref_q, m.local_pos, parents, fm < 0.5)
    after = ci.check_fk_positions(lq, lp, parents)
    gap = fm < 0.5
    e_before = np.linalg.norm(before - gp, axis=-1)[gap].mean()
    e_after = np.linalg.norm(after - gp, axis=-1)[gap].mean()
    assert e_after < 0.25 * e_before and e_after < 2.0
    np.testing.assert_allclose(after[~gap], gp[~gap], atol=1e-6)
