"""Metrics vs independent float64 NumPy transcriptions of the official formulas.

The references below are written from the formulas (LaFAN1 ``lafan1/benchmarks.py`` for L2Q / L2P /
NPSS; S-CVAE / DLow for ADE / FDE / SLDE / APD), with loops where natural, and never call the
library. Data: smooth random motions (scipy random rotations composed with small per-frame
increments, positions through a small joint tree).
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from inbetween_jax import metrics as M

RTOL, ATOL = 1e-5, 1e-6
PARENTS = [-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9]  # J = 11: root, two legs, spine
FEET = (3, 4, 7, 8)
B, T, J = 3, 16, len(PARENTS)


# ----------------------------------------------------------------------------- synthetic motion
def smooth_quats(rng, b, t, j, step=0.08):
    """(b, t, j, 4) wxyz unit quaternions: random start, small random per-frame increments, sign
    continuous over time."""
    rot = Rotation.random(b * j, random_state=rng)
    frames = [rot]
    for _ in range(t - 1):
        rot = Rotation.from_rotvec(rng.normal(scale=step, size=(b * j, 3))) * rot
        frames.append(rot)
    xyzw = np.stack([r.as_quat() for r in frames], axis=0)  # (t, b*j, 4)
    q = np.concatenate([xyzw[..., 3:], xyzw[..., :3]], axis=-1).reshape(t, b, j, 4).transpose(1, 0, 2, 3)
    for i in range(1, t):  # hemisphere continuity
        flip = np.sum(q[:, i] * q[:, i - 1], axis=-1) < 0
        q[:, i][flip] *= -1
    return q


def positions_from(quats, rng, root_speed=2.0):
    """Global positions (b, t, j, 3) in cm: smooth root path + bone offsets rotated by the
    parent's global rotation."""
    b, t, j, _ = quats.shape
    offsets = rng.normal(scale=15.0, size=(j, 3))
    root = np.cumsum(rng.normal(scale=root_speed, size=(b, t, 3)), axis=1) + np.array([0, 90.0, 0])
    pos = np.zeros((b, t, j, 3))
    pos[:, :, 0] = root
    for k in range(1, j):
        par = PARENTS[k]
        wxyz = quats[:, :, par].reshape(-1, 4)
        r = Rotation.from_quat(np.concatenate([wxyz[:, 1:], wxyz[:, :1]], axis=-1))
        pos[:, :, k] = pos[:, :, par] + r.apply(offsets[k]).reshape(b, t, 3)
    return pos


@pytest.fixture(scope="module")
def motion():
    rng = np.random.default_rng(0)
    gq = smooth_quats(rng, B, T, J)
    pq = smooth_quats(rng, B, T, J, step=0.05)
    pq = 0.7 * gq + 0.3 * pq * np.sign(np.sum(pq * gq, -1, keepdims=True))  # a "prediction" near gt
    pq /= np.linalg.norm(pq, axis=-1, keepdims=True)
    gp = positions_from(gq, np.random.default_rng(1))
    pp = positions_from(pq, np.random.default_rng(1)) + rng.normal(scale=0.5, size=gp.shape)
    return dict(gq=gq, pq=pq, gp=gp, pp=pp)


def close(actual, expected, rtol=RTOL, atol=ATOL):
    np.testing.assert_allclose(np.asarray(actual, np.float64), expected, rtol=rtol, atol=atol)


# ----------------------------------------------------------------------------- references
def ref_l2q(pq, gq):
    b, t = gq.shape[:2]
    vals = [np.sqrt(np.sum((pq[i, k] - gq[i, k]) ** 2)) for i in range(b) for k in range(t)]
    return np.mean(vals)


def ref_l2p(pp, gp, x_mean, x_std):
    b, t, j, _ = gp.shape
    p = pp.reshape(b, t, j * 3).transpose(0, 2, 1)  # official: (B, J*3, T)
    g = gp.reshape(b, t, j * 3).transpose(0, 2, 1)
    p = (p - x_mean) / x_std
    g = (g - x_mean) / x_std
    return np.mean(np.sqrt(np.sum((p - g) ** 2.0, axis=1)))


def ref_npss(gt, pred):
    gt_power = np.real(np.fft.fft(gt, axis=1)) ** 2
    pred_power = np.real(np.fft.fft(pred, axis=1)) ** 2
    gt_total = gt_power.sum(axis=1)
    pred_total = pred_power.sum(axis=1)
    b, t, d = gt.shape
    emd = np.zeros((b, d))
    for i in range(b):
        for c in range(d):
            cg = np.cumsum(gt_power[i, :, c] / gt_total[i, c])
            cp = np.cumsum(pred_power[i, :, c] / pred_total[i, c])
            emd[i, c] = np.sum(np.abs(cp - cg))
    return np.average(emd, weights=gt_total)


def ref_dist(a, b_):
    return np.sqrt(((a - b_) ** 2).sum(-1))


def ref_apd(samples):
    n, b = samples.shape[:2]
    out = []
    for k in range(b):
        total = 0.0
        for i in range(n):
            for j in range(n):
                if i != j:
                    total += np.linalg.norm((samples[i, k] - samples[j, k]).ravel())
        out.append(total / (n * (n - 1)))
    return np.mean(out)


# ----------------------------------------------------------------------------- LaFAN1 metrics
def test_l2q_matches_reference(motion):
    close(M.l2q(jnp.asarray(motion["pq"], jnp.float32), jnp.asarray(motion["gq"], jnp.float32)),
          ref_l2q(motion["pq"], motion["gq"]))


def test_l2q_hand_cases():
    ident = np.array([[[[1.0, 0, 0, 0]]]])
    close(M.l2q(ident, np.array([[[[0.0, 1, 0, 0]]]])), np.sqrt(2.0))
    close(M.l2q(ident, -ident), 2.0)  # sign sensitive: inputs must be sign continuous
    close(M.l2q(ident, ident), 0.0)


def test_l2p_matches_reference(motion):
    rng = np.random.default_rng(2)
    x_mean = rng.normal(scale=20.0, size=(1, J * 3, 1))
    x_std = rng.uniform(5.0, 40.0, size=(1, J * 3, 1))
    expected = ref_l2p(motion["pp"], motion["gp"], x_mean, x_std)
    pp, gp = jnp.asarray(motion["pp"], jnp.float32), jnp.asarray(motion["gp"], jnp.float32)
    close(M.l2p(pp, gp, x_mean, x_std), expected)
    close(M.l2p(pp, gp, x_mean.ravel(), x_std.ravel()), expected)  # (J*3,) stats


def test_l2p_hand_case():
    gt = np.zeros((1, 2, 1, 3))
    pred = np.array([[[[3.0, 0.0, 0.0]], [[0.0, 4.0, 0.0]]]])
    std = np.array([1.0, 2.0, 1.0]).reshape(1, 3, 1)
    # frame 0: |3/1| = 3, frame 1: |4/2| = 2 -> mean 2.5 (the mean cancels)
    close(M.l2p(pred, gt, np.full((1, 3, 1), 7.0), std), 2.5)


def test_npss_matches_reference(motion):
    gt = motion["gq"].reshape(B, T, -1)
    pred = motion["pq"].reshape(B, T, -1)
    expected = ref_npss(gt, pred)
    close(M.npss(jnp.asarray(gt, jnp.float32), jnp.asarray(pred, jnp.float32)), expected, rtol=2e-5)
    # (B, T, J, 4) is flattened like the official flatjoints
    close(M.npss(motion["gq"].astype(np.float32), motion["pq"].astype(np.float32)), expected, rtol=2e-5)
    assert expected > 1e-4  # the data is not trivially identical
    close(M.npss(gt.astype(np.float32), gt.astype(np.float32)), 0.0)
    assert M.fast_npss is M.npss


def test_npss_zero_power_no_nan(motion):
    zeros = jnp.zeros((2, 8, 5), jnp.float32)
    assert float(M.npss(zeros, zeros)) == 0.0
    assert np.isfinite(float(M.npss(zeros, jnp.ones((2, 8, 5)))))
    # one channel silent in both: it must simply drop out of the weighted average
    gt = motion["gq"].reshape(B, T, -1).copy()
    pred = motion["pq"].reshape(B, T, -1).copy()
    gt[:, :, 2] = 0.0
    pred[:, :, 2] = 0.0
    keep = [c for c in range(gt.shape[-1]) if c != 2]
    val = M.npss(gt.astype(np.float32), pred.astype(np.float32))
    assert np.isfinite(float(val))
    close(val, ref_npss(gt[:, :, keep], pred[:, :, keep]), rtol=2e-5)


# ----------------------------------------------------------------------------- S-CVAE / CAE
def test_ade_fde_slde_match_reference(motion):
    pp, gp = motion["pp"], motion["gp"]
    pj, gj = jnp.asarray(pp, jnp.float32), jnp.asarray(gp, jnp.float32)
    ade_ref = np.mean([ref_dist(pp[b, t, j], gp[b, t, j]) for b in range(B) for t in range(T) for j in range(J)])
    fde_ref = np.mean([ref_dist(pp[b, T - 1, j], gp[b, T - 1, j]) for b in range(B) for j in range(J)])
    slde_ref = np.mean([ref_dist(pp[b, T - 2, j], gp[b, T - 2, j]) for b in range(B) for j in range(J)])
    close(M.ade(pj, gj), ade_ref)
    close(M.ade(pj, gj, scale=0.01), 0.01 * ade_ref)
    close(M.fde(pj, gj), fde_ref)
    close(M.slde(pj, gj), slde_ref)
    assert abs(fde_ref - slde_ref) > 1e-3


def test_fde_slde_hand_case():
    gt = np.zeros((1, 3, 2, 3))
    pred = gt.copy()
    pred[0, 2, :, 0] = 3.0       # last frame off by 3 cm
    pred[0, 1, 0] = [0, 3, 4]    # frame before: joint 0 off by 5 cm, joint 1 exact
    close(M.fde(pred, gt), 3.0)
    close(M.slde(pred, gt), 2.5)
    close(M.ade(pred, gt, scale=0.01), 0.01 * (6.0 + 5.0) / 6.0)


def test_mpjpe_matches_reference(motion):
    pp, gp = motion["pp"], motion["gp"]
    prel = pp - pp[:, :, :1]
    grel = gp - gp[:, :, :1]
    errs = np.array([[[ref_dist(prel[b, t, j], grel[b, t, j]) for j in range(J)] for t in range(T)]
                     for b in range(B)])
    mean, std = M.mpjpe(jnp.asarray(pp, jnp.float32), jnp.asarray(gp, jnp.float32))
    close(mean, errs.mean(), rtol=1e-4)
    close(std, errs.std(), rtol=1e-4)
    mask = np.zeros((B, T))
    mask[:, 4:12] = 1.0  # a gap
    mean, std = M.mpjpe(pp.astype(np.float32), gp.astype(np.float32), mask=mask)
    close(mean, errs[:, 4:12].mean(), rtol=1e-4)
    close(std, errs[:, 4:12].std(), rtol=1e-4)
    # root alignment removes a global translation
    mean, std = M.mpjpe(gp + 100.0, gp)
    close(mean, 0.0, atol=1e-4)
    close(std, 0.0, atol=1e-4)


def test_apd_matches_reference(motion):
    rng = np.random.default_rng(3)
    samples = motion["gp"][None] + rng.normal(scale=3.0, size=(4,) + motion["gp"].shape)
    close(M.apd(jnp.asarray(samples, jnp.float32)), ref_apd(samples))
    close(M.apd(samples.astype(np.float32), scale=0.01), 0.01 * ref_apd(samples))


def test_apd_hand_cases():
    x = np.zeros((2, 1, 2, 1, 3))
    x[1, 0, 0, 0] = [3.0, 4.0, 0.0]
    x[1, 0, 1, 0] = [0.0, 0.0, 12.0]
    close(M.apd(x), 13.0)  # two samples: their distance, sqrt(9 + 16 + 144)
    close(M.apd(x[:1]), 0.0)
    close(M.apd(np.repeat(x[:1], 3, axis=0)), 0.0)


# ----------------------------------------------------------------------------- foot metrics
def test_foot_skating_weight_values():
    w = np.asarray(M.foot_skating_weight(jnp.array([0.0, 1.25, 2.5, 5.0, -1.0])))
    close(w, [1.0, 2.0 - np.sqrt(2.0), 0.0, 0.0, 1.0])
    close(M.foot_skating_weight(1.0, H=2.0), 2.0 - np.sqrt(2.0))


def ref_skating(pos, feet, H=2.5):
    b, t = pos.shape[:2]
    vals = []
    for i in range(b):
        for k in range(1, t):
            for f in feet:
                d = np.hypot(*(pos[i, k, f, [0, 2]] - pos[i, k - 1, f, [0, 2]]))
                vals.append(d * min(max(2.0 - 2.0 ** (pos[i, k, f, 1] / H), 0.0), 1.0))
    return np.mean(vals)


def ref_sliding(pos, feet, contacts):
    b, t = pos.shape[:2]
    vals = [contacts[i, k - 1, n] * contacts[i, k, n] *
            np.hypot(*(pos[i, k, f, [0, 2]] - pos[i, k - 1, f, [0, 2]]))
            for i in range(b) for k in range(1, t) for n, f in enumerate(feet)]
    return np.mean(vals)


def foot_motion(motion):
    pos = motion["pp"].copy()
    rng = np.random.default_rng(4)
    pos[..., 1] = rng.uniform(-0.5, 4.0, size=pos.shape[:-1])  # heights around the 2.5 cm band
    return pos


def test_foot_skating_matches_reference(motion):
    pos = foot_motion(motion)
    close(M.foot_skating(jnp.asarray(pos, jnp.float32), FEET), ref_skating(pos, FEET), rtol=1e-4)
    assert M.foot_skating_frames(pos.astype(np.float32), FEET).shape == (B, T - 1, len(FEET))


def test_foot_sliding_matches_reference(motion):
    pos = foot_motion(motion)
    rng = np.random.default_rng(5)
    contacts = (rng.uniform(size=(B, T, len(FEET))) > 0.4).astype(np.float64)
    close(M.foot_sliding(pos.astype(np.float32), FEET, contacts=contacts),
          ref_sliding(pos, FEET, contacts), rtol=1e-4)
    heights = pos[:, :, list(FEET), 1]
    close(M.foot_sliding(pos.astype(np.float32), FEET, height_threshold=2.0),
          ref_sliding(pos, FEET, (heights < 2.0).astype(np.float64)), rtol=1e-4)


def test_foot_hand_cases():
    pos = np.zeros((1, 3, 1, 3))
    pos[0, :, 0, 0] = [0.0, 1.0, 2.0]  # slides 1 cm / frame along X on the floor
    close(M.foot_skating(pos, (0,)), 1.0)
    close(M.foot_sliding(pos, (0,)), 1.0)
    close(M.foot_sliding(pos, (0,), contacts=np.array([[[1.0], [1.0], [0.0]]])), 0.5)
    lifted = pos.copy()
    lifted[..., 1] = 2.5  # at H: no skating counted; above the 2 cm contact threshold
    close(M.foot_skating(lifted, (0,)), 0.0)
    close(M.foot_sliding(lifted, (0,), height_threshold=2.0), 0.0)
    vertical = np.zeros((1, 3, 1, 3))
    vertical[0, :, 0, 1] = [0.0, -1.0, 0.0]  # vertical motion is not sliding
    close(M.foot_skating(vertical, (0,)), 0.0)


# ----------------------------------------------------------------------------- stitching
def test_mmpe_matches_reference(motion):
    fwd, bwd = motion["pp"], motion["gp"]
    m = T // 2
    expected = np.mean([ref_dist(fwd[b, m, j], bwd[b, m, j]) for b in range(B) for j in range(J)])
    close(M.mmpe(jnp.asarray(fwd, jnp.float32), jnp.asarray(bwd, jnp.float32)), expected)
    hand_f = np.zeros((1, 5, 2, 3))
    hand_b = hand_f.copy()
    hand_b[0, 2, 0] = [3.0, 4.0, 0.0]  # middle of L = 5 is frame 2
    hand_b[0, 0, 1] = [100.0, 0.0, 0.0]  # off the middle: ignored
    close(M.mmpe(hand_f, hand_b), 2.5)


# ----------------------------------------------------------------------------- jit
def test_all_metrics_jit(motion):
    pq, gq = jnp.asarray(motion["pq"], jnp.float32), jnp.asarray(motion["gq"], jnp.float32)
    pp, gp = jnp.asarray(motion["pp"], jnp.float32), jnp.asarray(motion["gp"], jnp.float32)
    stats = (jnp.zeros((1, J * 3, 1)), jnp.full((1, J * 3, 1), 10.0))
    cases = [
        (M.l2q, (pq, gq)), (M.l2p, (pp, gp) + stats), (M.npss, (gq, pq)), (M.ade, (pp, gp)),
        (M.fde, (pp, gp)), (M.slde, (pp, gp)), (M.mpjpe, (pp, gp)), (M.apd, (jnp.stack([pp, gp]),)),
        (M.mmpe, (pp, gp)), (lambda p: M.foot_skating(p, FEET), (pp,)),
        (lambda p: M.foot_sliding(p, FEET, height_threshold=95.0), (pp,)),
    ]
    for fn, args in cases:
        eager = jax.tree_util.tree_leaves(fn(*args))
        jitted = jax.tree_util.tree_leaves(jax.jit(fn)(*args))
        for a, b in zip(eager, jitted):
            assert np.isfinite(float(b))
            close(b, np.asarray(a, np.float64), rtol=1e-5)
