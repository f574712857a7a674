"""Metrics of N samples of the same keyframes (inbetween_jax/evaluation/samples.py) against brute-force
re-derivations and the L2P of inbetween_jax.metrics; real CMU windows with Slerp and perturbed copies."""
import numpy as np
import pytest

from inbetween_jax import metrics
from inbetween_jax.baselines import interpolate_transition
from inbetween_jax.data import l2p_stats, load_dataset
from inbetween_jax.evaluation import samples as S

N_PAST, N = 10, 12


@pytest.fixture(scope="module")
def windows():
    w = load_dataset(None, "benchmark").take(slice(0, 6))
    return w, l2p_stats(w.global_pose()[1])


def test_pairwise_joint_distance_is_the_mean_over_ordered_pairs():
    rng = np.random.default_rng(0)
    pos = rng.normal(size=(3, 2, 4, 5, 3))
    brute = np.mean([np.linalg.norm(pos[i, b, t, j] - pos[k, b, t, j])
                     for i in range(3) for k in range(3) if i != k
                     for b in range(2) for t in range(4) for j in range(5)])
    np.testing.assert_allclose(S.pairwise_joint_distance(pos), brute, rtol=1e-10)
    assert S.pairwise_joint_distance(pos[:1]) == 0.0


def test_per_window_l2p_averages_to_the_official_l2p(windows):
    (w, (xm, xs)) = windows
    q, r = interpolate_transition(w.local_quats.astype(np.float64), w.root_pos.astype(np.float64), N_PAST, N)
    pos = S.window_positions(w, q, r)
    gt = S.window_positions(w, w.local_quats[:, N_PAST:N_PAST + N], w.root_pos[:, N_PAST:N_PAST + N])
    per = S.per_window_l2p(pos, gt, xm, xs)
    assert per.shape == (len(w),)
    np.testing.assert_allclose(per.mean(), float(metrics.l2p(pos, gt, xm, xs)), rtol=1e-5)


def test_reach_counts_samples_that_snap_onto_the_target():
    t = np.linspace(0.0, 1.0, 12)[None, None, :, None, None] * np.ones((2, 3, 1, 4, 3))   # a steady walk
    assert S.reach_share(t) == 1.0
    snapped = t.copy()
    snapped[0, :, -1] += 1.0                     # sample 0 jumps onto a key far away
    assert S.reach_share(snapped) == 0.5


def test_sample_metrics_of_slerp_and_of_spread_samples(windows):
    (w, (xm, xs)) = windows
    q, r = interpolate_transition(w.local_quats.astype(np.float64), w.root_pos.astype(np.float64), N_PAST, N)
    one = S.sample_metrics(w, N_PAST, N, q, r, xm, xs)
    assert one["APD"] == 0.0 and one["pairwise_cm"] == 0.0
    assert one["best_L2P"] == pytest.approx(one["mean_L2P"]) and one["reach"] == 1.0
    lo, hi = N_PAST - 1, N_PAST + N + 1              # the capture's own share, by the rule computed here
    cap = np.linalg.norm(np.diff(S.window_positions(w, w.local_quats[:, lo:hi], w.root_pos[:, lo:hi]), axis=1),
                         axis=-1).mean(-1)                                                    # (B, N + 1) steps
    assert one["reach_truth"] == pytest.approx(np.mean(cap[:, -1] <= 2.0 * np.median(cap[:, 1:-1], -1)))
    shifts = np.array([-8.0, 0.0, 8.0])[:, None, None, None] * np.array([1.0, 0.0, 0.0])   # three root offsets (cm)
    qs, rs = np.broadcast_to(q, (3,) + q.shape), r[None] + shifts
    many = S.sample_metrics(w, N_PAST, N, qs, rs, xm, xs)
    np.testing.assert_allclose(many["pairwise_cm"], (8 + 16 + 8) * 2 / 6, rtol=1e-6)   # |i - j| x 8 cm
    np.testing.assert_allclose(many["APD"], float(metrics.apd(np.stack([S.window_positions(w, a, b) for a, b in
                                                                        zip(qs, rs)]), scale=0.01)), rtol=1e-6)
    assert many["best_L2P"] <= one["mean_L2P"] + 1e-9 <= many["mean_L2P"]
    assert many["best_cm"] < many["mean_cm"]
    with pytest.raises(FloatingPointError):
        S.sample_metrics(w, N_PAST, N, qs, rs * np.nan, xm, xs)


def test_infill_json_spread_of_samples_that_differ_by_a_known_shift():
    import dataclasses

    from inbetween_jax.data import load_motions
    from inbetween_jax.data.features import detect_unit_scale
    from inbetween_jax.evaluation.samples import sample_spread
    m = load_motions(None, "train")[0].slice(0, 20)
    moved = []
    for k in range(3):                                   # root (and so every joint) k units along x
        pos = m.local_pos.copy()
        pos[:, 0, 0] += 5.0 * k
        moved.append(dataclasses.replace(m, local_pos=pos))
    cm = detect_unit_scale(m.skeleton)
    out = sample_spread(moved)
    np.testing.assert_allclose(out["samples_pairwise_cm"], 5.0 * cm * (1 + 2 + 1) * 2 / 6, rtol=1e-3)
    np.testing.assert_allclose(out["samples_spread_cm"], [5.0 * cm * 1.5, 5.0 * cm, 5.0 * cm * 1.5], rtol=1e-3)
    assert sample_spread(moved[:1]) == {}
