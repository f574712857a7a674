"""Quaternions against scipy's Rotation; FK against hand-computed chains; jit / vmap / grad of FK."""
import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from inbetween_jax.geometry import (bone_lengths, dct, dct_matrix, forward_kinematics, idct, inverse_kinematics,
                                    local_positions, quat_between, quat_fix_sign, quat_fix_sign_np,
                                    quat_from_euler, quat_from_forward_up, quat_from_matrix, quat_inv, quat_mul,
                                    quat_normalize, quat_rotate, quat_slerp, quat_to_euler, quat_to_forward_up,
                                    quat_to_matrix)

ORDERS = ["".join(p) for p in itertools.permutations("xyz")]


def wxyz(r: Rotation) -> np.ndarray:
    return r.as_quat(scalar_first=True)


def same_rotation(a, b, atol=1e-5):
    """Quaternions equal up to sign."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.allclose(np.abs(np.sum(a * b, -1)), 1.0, atol=atol)


@pytest.fixture(scope="module")
def rots():
    return Rotation.random(64, random_state=0), Rotation.random(64, random_state=1)


@pytest.mark.parametrize("backend", [np.asarray, jnp.asarray])
def test_mul_inv_rotate_match_scipy(rots, backend):
    ra, rb = rots
    qa, qb = backend(wxyz(ra)), backend(wxyz(rb))
    assert same_rotation(quat_mul(qa, qb), wxyz(ra * rb))
    assert same_rotation(quat_inv(qa), wxyz(ra.inv()))
    v = np.random.default_rng(0).normal(size=(64, 3))
    np.testing.assert_allclose(quat_rotate(qa, backend(v)), ra.apply(v), atol=1e-5)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_roundtrip_matches_scipy(order):
    ang = np.random.default_rng(1).uniform(-np.pi, np.pi, size=(200, 3))
    ang[:, 1] *= 0.45  # keep the middle angle away from gimbal lock for the angle comparison
    ref = Rotation.from_euler(order.upper(), ang)  # upper case = intrinsic, the BVH convention
    for backend, tol in ((np.asarray, 1e-10), (jnp.asarray, 2e-5)):
        q = quat_from_euler(backend(ang.astype(np.float64 if backend is np.asarray else np.float32)), order)
        assert same_rotation(q, wxyz(ref), atol=tol)
        np.testing.assert_allclose(quat_to_euler(q, order), ang, atol=tol * 20)


def test_matrix_conversions_match_scipy(rots):
    ra, _ = rots
    np.testing.assert_allclose(quat_to_matrix(wxyz(ra)), ra.as_matrix(), atol=1e-12)
    assert same_rotation(quat_from_matrix(ra.as_matrix()), wxyz(ra), atol=1e-10)
    assert same_rotation(quat_from_matrix(jnp.asarray(ra.as_matrix(), jnp.float32)), wxyz(ra), atol=1e-5)


def test_slerp_matches_scipy(rots):
    ra, rb = rots
    ts = np.linspace(0, 1, 7)
    for i in range(8):
        ref = Slerp([0, 1], Rotation.concatenate([ra[i], rb[i]]))(ts)
        got = quat_slerp(wxyz(ra[i])[None], wxyz(rb[i])[None], ts)
        assert same_rotation(got, wxyz(ref), atol=1e-6)
    # jit path and the linear fallback for near-identical inputs stay unit and finite
    q = jnp.asarray(wxyz(ra[:4]), jnp.float32)
    out = jax.jit(quat_slerp)(q, q, 0.3)
    np.testing.assert_allclose(jnp.linalg.norm(out, axis=-1), 1.0, atol=1e-6)


def test_between_and_forward_up():
    u = np.array([[1.0, 0, 0], [0, 1.0, 0.2]])
    v = np.array([[0, 0, 2.0], [0.3, -1.0, 0]])
    q = quat_between(u, v)
    got = quat_rotate(q, u)
    np.testing.assert_allclose(got / np.linalg.norm(got, axis=-1, keepdims=True),
                               v / np.linalg.norm(v, axis=-1, keepdims=True), atol=1e-12)
    r = wxyz(Rotation.random(10, random_state=3))
    fu = quat_to_forward_up(r)
    np.testing.assert_allclose(fu[:, :3], Rotation.from_quat(r, scalar_first=True).apply([0, 0, 1]), atol=1e-12)
    assert same_rotation(quat_from_forward_up(fu), r, atol=1e-10)


def test_sign_continuity():
    r = wxyz(Rotation.from_euler("y", np.linspace(0, 6 * np.pi, 50)[:, None]))
    flipped = r * np.where(np.arange(50) % 3 == 0, -1.0, 1.0)[:, None]
    fixed = quat_fix_sign_np(flipped)
    assert np.all(np.sum(fixed[1:] * fixed[:-1], -1) > 0)
    np.testing.assert_allclose(quat_fix_sign(jnp.asarray(flipped)), fixed, atol=1e-6)
    assert same_rotation(fixed, r)


def test_fk_two_bone_chain_by_hand():
    # root at (1, 2, 3) turned 90 deg about Y; bone 1 offset (0, 0, 10) bent 90 deg about X; bone 2 (0, 5, 0)
    parents = (-1, 0, 1)
    rot_y = wxyz(Rotation.from_euler("y", 90, degrees=True))
    rot_x = wxyz(Rotation.from_euler("x", 90, degrees=True))
    lq = np.stack([rot_y, rot_x, [1.0, 0, 0, 0]])
    lp = np.array([[1.0, 2.0, 3.0], [0, 0, 10.0], [0, 5.0, 0]])
    gq, gp = forward_kinematics(lq, lp, parents)
    # joint 1: root + Ry(90) (0,0,10) = (1,2,3) + (10,0,0)
    # joint 2: joint1 + Ry(90) Rx(90) (0,5,0) = joint1 + Ry(90) (0,0,5) = joint1 + (5,0,0)
    np.testing.assert_allclose(gp, [[1, 2, 3], [11, 2, 3], [16, 2, 3]], atol=1e-12)
    assert same_rotation(gq[2], wxyz(Rotation.from_euler("y", 90, degrees=True) * Rotation.from_euler("x", 90, degrees=True)))
    np.testing.assert_allclose(bone_lengths(gp, parents), [10.0, 5.0], atol=1e-12)


def test_ik_inverts_fk_and_jax_transforms():
    rng = np.random.default_rng(0)
    parents = (-1, 0, 1, 2, 1, 4)
    lq = quat_normalize(rng.normal(size=(3, 8, 6, 4)), eps=0.0)
    lp = local_positions(rng.normal(size=(3, 8, 3)), rng.normal(size=(6, 3)))
    gq, gp = forward_kinematics(lq, lp, parents)
    lq2, lp2 = inverse_kinematics(gq, gp, parents)
    assert same_rotation(lq2, lq, atol=1e-10)
    np.testing.assert_allclose(lp2, lp, atol=1e-10)

    fk = jax.jit(lambda q, p: forward_kinematics(q, p, parents)[1])
    jq, jp = jnp.asarray(lq, jnp.float32), jnp.asarray(lp, jnp.float32)
    np.testing.assert_allclose(fk(jq, jp), gp, atol=1e-4)
    np.testing.assert_allclose(jax.vmap(fk)(jq, jp), gp, atol=1e-4)
    # gradient of the end effector's x w.r.t. the root position's x is exactly 1
    g = jax.grad(lambda p: fk(jq, p)[..., 5, 0].sum())(jp)
    np.testing.assert_allclose(g[..., 0, 0], 1.0, atol=1e-6)
    # gradient wrt rotations matches finite differences
    f = lambda q: jnp.sum(fk(quat_normalize(q), jp) ** 2)
    gq_ = jax.grad(f)(jq)
    d = jnp.zeros_like(jq).at[0, 0, 2, 1].set(1e-2)
    fd = (f(jq + d) - f(jq - d)) / 2e-2
    np.testing.assert_allclose(gq_[0, 0, 2, 1], fd, rtol=2e-2)


def test_fk_rejects_bad_parents():
    with pytest.raises(ValueError, match="parents"):
        forward_kinematics(np.zeros((2, 4)), np.zeros((2, 3)), (0, 0))
    with pytest.raises(ValueError, match="joints"):
        forward_kinematics(np.zeros((3, 4)), np.zeros((3, 3)), (-1, 0))


def test_dct_roundtrip_and_orthonormal():
    d = dct_matrix(20)
    np.testing.assert_allclose(d @ d.T, np.eye(20), atol=1e-5)
    x = jnp.asarray(np.random.default_rng(0).normal(size=(2, 20, 7)), jnp.float32)
    np.testing.assert_allclose(idct(dct(x)), x, atol=1e-5)
    from scipy.fft import dct as sdct
    np.testing.assert_allclose(dct(x), sdct(np.asarray(x), axis=1, norm="ortho"), atol=1e-4)


def test_quat_align_flips_into_the_reference_hemisphere_in_numpy_and_jax():
    from inbetween_jax.geometry import quat_align
    rng = np.random.default_rng(3)
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    ref = rng.normal(size=(5, 4))
    out = quat_align(q, ref)
    assert isinstance(out, np.ndarray) and out.dtype == np.float64
    assert np.all(np.sum(out * ref, -1) >= 0)
    np.testing.assert_allclose(np.abs(out), np.abs(q))                 # the same rotations, only signs flipped
    assert np.any(np.sum(q * ref, -1) < 0)                             # this draw needs a flip somewhere
    np.testing.assert_allclose(np.asarray(quat_align(jnp.asarray(q), jnp.asarray(ref))), out.astype(np.float32),
                               atol=1e-7)
