"""Interaction in-betweening: representation, spaces, nets, rollout and overfitting on real clips.

Real clips: the shipped CMU mocap (embedded default) paired as two characters (constructed pairs).
"""
from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

from inbetween_jax.data.datasets import EMBEDDED_DIR
from inbetween_jax.geometry import dct, idct
from inbetween_jax.geometry.heading import yaw_matrix
from inbetween_jax.models.interaction import data as idata
from inbetween_jax.models.interaction import batches as ibatches
from inbetween_jax.models.interaction import features as ifeat
from inbetween_jax.models.interaction import layers as inets
from inbetween_jax.models.interaction import model as ia
from inbetween_jax.models.interaction.config import get_config

CFG = get_config("tiny")


@pytest.fixture(scope="module")
def pairs():
    return idata.load_pairs("embedded")


def _rand_space(rng, shape):
    return yaw_matrix(rng.uniform(-np.pi, np.pi, shape)), rng.normal(0, 2, shape + (3,)) * [1, 0, 1]


def test_dct_idct_round_trip():
    x = jnp.asarray(np.random.default_rng(0).normal(size=(3, 2, 30, 5, 9)), jnp.float32)
    c = dct(x, axis=2)
    np.testing.assert_allclose(idct(c, n=30, axis=2), x, atol=1e-4)
    # truncation keeps the smooth part: a constant signal survives with one coefficient
    const = jnp.ones((1, 30, 4))
    np.testing.assert_allclose(idct(dct(const, num_coeffs=1), n=30), const, atol=1e-5)


def test_graph_conv_shapes_and_locality():
    g = inets.GraphConv(6, 8, 5, rngs=nnx.Rngs(0))
    g.adj[...] = jnp.eye(6)
    x = jnp.asarray(np.random.default_rng(1).normal(size=(2, 6, 8)), jnp.float32)
    y = g(x)
    assert y.shape == (2, 6, 5)
    y2 = g(x.at[:, 3].add(1.0))
    changed = np.any(np.abs(np.asarray(y2 - y)) > 1e-6, axis=(0, 2))
    assert changed.tolist() == [False, False, False, True, False, False]   # identity adjacency: no mixing
    g.adj[...] = jnp.ones((6, 6))
    assert np.all(np.abs(np.asarray(g(x.at[:, 3].add(1.0)) - g(x))) > 1e-6)


def test_convgcn_and_film_shapes():
    m = inets.ConvGCN(7, 15, 9, 9, 16, 15 * 9, 4, 2, rngs=nnx.Rngs(0))
    h, out = m(jnp.ones((3, 7, 15, 9)), jnp.ones((3, 7, 9)))
    assert h.shape == (3, 7, 16) and out.shape == (3, 7, 135)
    f = inets.FiLM(4, 16, rngs=nnx.Rngs(1))
    g, b = f(jnp.ones((3, 7, 4)))
    assert g.shape == b.shape == (3, 7, 16)
    np.testing.assert_allclose(inets.film(h, jnp.zeros_like(g), jnp.zeros_like(b)), h)
    np.testing.assert_allclose(inets.film(h, jnp.ones_like(g), jnp.ones_like(b)), 2 * h + 1, rtol=1e-6)


def test_periodic_ae_parameterisation():
    pae = inets.PeriodicAE(10, 30, 3, 8, rngs=nnx.Rngs(0))
    x = jnp.asarray(np.random.default_rng(2).normal(size=(4, 30, 10)), jnp.float32)
    recon, h, prm = pae(x)
    assert recon.shape == x.shape and h.shape == (4, 30, 3)
    assert np.all((np.asarray(prm["f"]) > 0) & (np.asarray(prm["f"]) <= 0.5))
    t = jnp.arange(30) - 14.5
    expect = prm["a"][:, None] * jnp.sin(2 * jnp.pi * (prm["f"][:, None] * t[None, :, None] + prm["phi"][:, None])) \
        + prm["b"][:, None]
    np.testing.assert_allclose(h, expect, atol=1e-5)


def test_spaces_are_invertible(pairs):
    rng = np.random.default_rng(3)
    feats = pairs[0].feats[:, :30].astype(np.float64)                       # (2, 30, J, 9) real frames
    R, t = _rand_space(rng, (2,))
    back = ifeat.apply_space(ifeat.to_space(feats, R[:, None], t[:, None]), R[:, None], t[:, None])
    np.testing.assert_allclose(back, feats, atol=1e-6)
    # cross-space transform (Eq. 2) and its inverse on a batch of real samples
    s = ifeat.keyframe_sample(pairs[0].feats, 0, 30, 25, pairs[0].forward_axis)
    coarse = jnp.asarray(s["x"][None], jnp.float32) * jnp.asarray([0.01] * 3 + [1] * 6)
    rel_R, rel_t = jnp.asarray(s["rel_R"][None]), jnp.asarray(s["rel_t"][None]) * 0.01
    fa = pairs[0].forward_axis
    rel = ia.cross_space(coarse, rel_R, rel_t, fa)
    np.testing.assert_allclose(ia.cross_space_inverse(rel, coarse[:, ::-1], rel_R, rel_t, fa), coarse, atol=1e-5)
    # the other character's root is at the origin of its own root space, facing +Z
    other_in_own = ia.cross_space(coarse[:, ::-1], rel_R[:, ::-1], rel_t[:, ::-1], fa)   # sanity: finite
    assert np.all(np.isfinite(np.asarray(other_in_own)))
    # relative_space agrees with going through the world
    world = ifeat.apply_space(s["x"][0], s["world_R"][0], s["world_t"][0])
    in_b = ifeat.to_space(world, s["world_R"][1], s["world_t"][1])
    np.testing.assert_allclose(ifeat.apply_space(s["x"][0], s["rel_R"][0], s["rel_t"][0]), in_b, atol=1e-3)


@pytest.mark.parametrize("mirror", [False, True])
def test_keyframe_sampling_origin_and_forward(pairs, mirror):
    rng = np.random.default_rng(4)
    tr = idata.split_pairs(pairs, "train")
    b = ibatches.sample_batch(tr, rng, 16, length=50, key_range=(25, 30), mirror=mirror)
    kp = b["keypose"]                                                        # (B, 2, J, 9)
    np.testing.assert_allclose(kp[..., 0, [0, 2]], 0.0, atol=1e-5)          # keyframe root at the origin
    yaw = ifeat.facing_yaw(kp[..., 0, :].astype(np.float64), tr[0].forward_axis)
    np.testing.assert_allclose(np.cos(yaw), 1.0, atol=1e-4)                 # ... facing +Z
    # the keyframe lies inside the window here: the window's frame equals the keypose
    found = [np.min(np.abs(b["x"][i] - kp[i][:, None]).max(axis=(0, 2, 3))) for i in range(16)]
    assert max(found) < 1e-5
    assert b["x"].shape[:3] == (16, 2, 50)


def test_mirror_is_an_involution(pairs):
    f = pairs[0].feats[:, :10]
    mm = pairs[0].skeleton.mirror_map()
    np.testing.assert_allclose(ifeat.mirror_feats(ifeat.mirror_feats(f, mm), mm), f)
    assert not np.allclose(ifeat.mirror_feats(f, mm), f)


def test_paired_bvh_loader_real_files(tmp_path):
    a, b = os.path.join(EMBEDDED_DIR, "02_01.bvh"), os.path.join(EMBEDDED_DIR, "02_02.bvh")
    os.symlink(a, tmp_path / "hug_A.bvh")
    os.symlink(b, tmp_path / "hug_B.bvh")
    ps = idata.load_pairs(str(tmp_path))
    assert len(ps) == 1 and ps[0].name == "hug" and not ps[0].constructed
    p = idata.load_pair(a, b)
    np.testing.assert_allclose(ps[0].feats, p.feats)
    # pairs list file takes precedence and is read relative to the folder
    (tmp_path / "pairs.txt").write_text("hug_B.bvh hug_A.bvh  # swapped\n")
    ps2 = idata.load_pairs(str(tmp_path))
    np.testing.assert_allclose(ps2[0].feats[0], p.feats[1])


def test_constructed_pair_faces_partner(pairs):
    p = pairs[0]
    assert p.constructed
    r = p.feats[:, 0, 0]
    ya = ifeat.facing_yaw(r[0].astype(np.float64), p.forward_axis)
    yb = ifeat.facing_yaw(r[1].astype(np.float64), p.forward_axis)
    assert abs(np.cos(ya - yb) + 1) < 1e-4                                   # facing each other
    d = (r[1, :3] - r[0, :3]) * [1, 0, 1]
    np.testing.assert_allclose(np.linalg.norm(d), 150.0, atol=1e-3)
    np.testing.assert_allclose(d / 150.0, [np.sin(ya), 0, np.cos(ya)], atol=1e-4)


def test_rollout_stops_at_threshold(pairs):
    params = ia.init_params(jax.random.key(0), CFG, pairs[0].feats.shape[2])
    tr = idata.split_pairs(pairs, "train")
    b = ibatches.sample_batch(tr, np.random.default_rng(5), 3, 50, (50, 70))
    w = b["x"][:, :, :20]
    fa = tr[0].forward_axis
    run = jax.jit(lambda thr: ia.rollout(params, w, b["keypose"], b["rel_R"], b["rel_t"], jax.random.key(1),
                                         CFG, fa, 5, threshold=thr))
    frames, length = run(1e9)                                                 # reached after the first step
    assert frames.shape == (3, 2, 50) + w.shape[3:]
    assert np.all(np.asarray(length) == 10)
    np.testing.assert_allclose(frames[:, :, 10:], jnp.repeat(frames[:, :, 9:10], 40, axis=2))
    frames, length = run(-1.0)                                                # never reached
    assert np.all(np.asarray(length) == 50)
    assert not np.allclose(frames[:, :, 10:20], frames[:, :, 20:30])
    # between: stops exactly at the first step whose last frame is within the threshold of both keyposes
    d = np.stack([np.asarray(ia.keypose_distance(frames[:, :, 10 * k + 9], b["keypose"])).max(1) for k in range(5)], 1)
    thr = float(np.median(d))
    _, length = run(thr)
    expect = [10 * (int(np.argmax(row < thr)) + 1) if np.any(row < thr) else 50 for row in d]
    assert np.asarray(length).tolist() == expect
    # diverse samples by vmap over keys
    many, _ = ia.sample_rollouts(params, w, b["keypose"], b["rel_R"], b["rel_t"], jax.random.key(2), CFG,
                                 fa, 2, 3, threshold=-1.0)
    assert many.shape[:2] == (3, 3) and not np.allclose(many[0], many[1])


def test_plain_dict_params_match_the_nnx_modules(pairs):
    """init_params' plain dicts hold the nnx modules' initial values, and generator_step on them equals the nnx
    Generator called directly."""
    J = pairs[0].feats.shape[2]
    key = jax.random.key(3)
    params = ia.init_params(key, CFG, J)
    gen = ia.Generator(J, CFG, rngs=nnx.Rngs(jax.random.split(key, 4)[0]))
    _, state = nnx.split(gen)
    ref_leaves = [np.asarray(v) for v in jax.tree.leaves(state)]
    got = [np.asarray(v) for v in jax.tree.leaves(params["gen"])]
    assert len(got) == len(ref_leaves) and all(np.array_equal(a, b) for a, b in zip(got, ref_leaves))
    assert all(isinstance(v, dict) for v in params.values())
    b = ibatches.sample_batch(idata.split_pairs(pairs, "train"), np.random.default_rng(6), 2, 50, (50, 70))
    fa = np.asarray(pairs[0].forward_axis, np.float32)
    out = ia.generator_step(params["gen"], b["x"][:, :, :20], b["keypose"], b["rel_R"], b["rel_t"],
                            jax.random.key(4), CFG, fa)
    c_in = ia._to_nodes(dct(jnp.concatenate([b["x"][:, :, :20], jnp.repeat(b["x"][:, :, 19:20], 10, 2)], 2),
                            axis=2, num_coeffs=CFG.model.dct_coeffs))
    _, res = gen.enc(c_in, b["keypose"].reshape(4, J, 9))
    coarse = idct(ia._from_nodes(c_in + res.reshape(c_in.shape), 2), n=30, axis=2)[:, :, 20:]
    np.testing.assert_allclose(out["coarse"], coarse, rtol=1e-6, atol=1e-7)
    with pytest.raises(ValueError, match="gen parameters do not match"):
        ia.generator_step(params["ref"], b["x"][:, :, :20], b["keypose"], b["rel_R"], b["rel_t"],
                          jax.random.key(4), CFG, fa)


def test_two_character_interpolation_on_real_frames(pairs):
    from inbetween_jax.baselines import two_character_interpolation
    s = ifeat.keyframe_sample(pairs[0].feats, 0, 40, 39, pairs[0].forward_axis)
    last, key = s["x"][None, :, 0].astype(np.float32), s["keypose"][None].astype(np.float32)
    out = np.asarray(two_character_interpolation(last, key, 9))                 # (1, 2, 9, J, 9)
    t = np.arange(1, 10)[:, None, None] / 10.0
    np.testing.assert_allclose(out[0, :, :, :, :3], last[0, :, None, :, :3] + t * (key - last)[0, :, None, :, :3],
                               atol=1e-3)
    fwd, up = out[..., 3:6], out[..., 6:9]
    np.testing.assert_allclose(np.linalg.norm(fwd, axis=-1), 1.0, atol=1e-4)
    np.testing.assert_allclose(np.sum(fwd * up, -1), 0.0, atol=1e-4)
    same = np.asarray(two_character_interpolation(key, key, 5))
    np.testing.assert_allclose(same, np.repeat(key[:, :, None], 5, 2), atol=1e-4)


def test_frechet_distance_matches_the_diagonal_closed_form():
    from inbetween_jax.metrics import frechet_distance
    rng = np.random.default_rng(7)
    a = rng.normal(0.0, 1.0, (4000, 3)) * [1.0, 2.0, 0.5]
    b = rng.normal(0.3, 1.0, (4000, 3)) * [1.5, 1.0, 0.5] + [0.0, 1.0, 0.0]
    # uncorrelated columns: the Gaussians' Frechet distance is sum (ma - mb)^2 + (sa - sb)^2 per dimension
    ref = np.sum((a.mean(0) - b.mean(0)) ** 2) + np.sum((a.std(0, ddof=1) - b.std(0, ddof=1)) ** 2)
    assert abs(frechet_distance(a, b) - ref) < 0.02
    assert abs(frechet_distance(a, a)) < 1e-6


@pytest.mark.parametrize("name, side", [("cmu", 0), ("lafan1", 2)])
def test_mirrored_features_are_the_features_of_the_mirrored_motion(name, side):
    """``mirror_feats`` against the independent route: the features of the motion mirrored on its rig
    (``Motion.mirrored``).  On LaFAN1's rig (left-right along local z) the forward vectors flip too."""
    from conftest import CLIP_A, HAS_LAFAN1, LAFAN1_DIR
    if name == "lafan1" and not HAS_LAFAN1:
        pytest.skip("LaFAN1 BVH files not found")
    from inbetween_jax.data import read_bvh
    path = CLIP_A if name == "cmu" else os.path.join(LAFAN1_DIR, "walk4_subject1.bvh")
    m = read_bvh(path, 0, 40)
    assert ifeat.skeleton_side_axis(m.skeleton) == side
    ref = ifeat.world_joint_features(m.mirrored())
    got = ifeat.mirror_feats(ifeat.world_joint_features(m), m.skeleton.mirror_map(), side)
    np.testing.assert_allclose(got, ref, atol=1e-6)


@pytest.mark.parametrize("cin,cout,k,n", [(9, 8, 3, 15), (8, 8, 3, 15), (4, 6, 5, 12)])
def test_banded_conv_equals_the_flax_conv_and_its_gradients(cin, cout, k, n):
    """layers.conv_same (one matmul with the kernel's banded matrix) against nnx.Conv itself: values and the
    gradients for the input, kernel and bias."""
    from inbetween_jax.models.interaction.layers import conv_same
    conv = nnx.Conv(cin, cout, k, rngs=nnx.Rngs(3))
    conv.bias[...] = jax.random.normal(jax.random.key(4), (cout,))
    x = jax.random.normal(jax.random.key(5), (6, n, cin))
    np.testing.assert_allclose(conv_same(conv, x), conv(x), atol=1e-5)
    w = jax.random.normal(jax.random.key(6), (6, n, cout))             # a cotangent
    graphdef, params = nnx.split(conv)

    def loss(apply, p, xx):
        return jnp.sum(apply(nnx.merge(graphdef, p), xx) * w)
    got = jax.grad(lambda p, xx: loss(conv_same, p, xx), argnums=(0, 1))(params, x)
    want = jax.grad(lambda p, xx: loss(lambda c, v: c(v), p, xx), argnums=(0, 1))(params, x)
    for g, r in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
        np.testing.assert_allclose(g, r, rtol=1e-5, atol=1e-4)
    assert len(jax.tree.leaves(got)) == 3                               # bias, kernel, input
