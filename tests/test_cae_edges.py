"""The network's fill meets each keyframe at the capture's speed (models/cae/edges.match_edge_velocity;
model.net_edge_fade): pure math on synthetic curves, and the shipped CAE through ``infill``'s path on a real walk."""
import numpy as np

from inbetween_jax.models.cae.edges import match_edge_velocity


def _curves():
    t = np.arange(80, dtype=np.float64)
    x = np.stack([np.sin(t / 6.0), 0.05 * t + np.cos(t / 9.0), 0.3 * np.sin(t / 4.0 + 1.0)])[None]   # (1, 3, 80)
    mask = np.ones((1, 1, 80), np.float32)
    mask[..., 20:50] = 0.0
    return x.astype(np.float32), mask


def test_the_first_and_last_steps_become_the_captures_and_the_keyframes_stay():
    x, mask = _curves()
    line = x.copy()
    w = (np.arange(20, 50) - 19) / 31.0
    line[..., 20:50] = x[..., 19:20] + w * (x[..., 50:51] - x[..., 19:20])          # a straight-line fill
    out = match_edge_velocity(line, x * mask, mask, 0.3, slice(0, 3))
    v0 = (3 * x[0, :, 19] - 4 * x[0, :, 18] + x[0, :, 17]) / 2                     # the capture's velocities
    v1 = (-3 * x[0, :, 50] + 4 * x[0, :, 51] - x[0, :, 52]) / 2
    first, last = out[0, :, 20] - x[0, :, 19], x[0, :, 50] - out[0, :, 49]
    scale = np.abs(np.concatenate([v0, v1])).max()
    # the added first step is (1 - 1/L1)^2 of the difference: within 10 % of the scale
    np.testing.assert_allclose(first, v0, atol=0.1 * scale)
    np.testing.assert_allclose(last, v1, atol=0.1 * scale)
    assert np.abs(line[0, :, 20] - x[0, :, 19] - v0).max() > 0.2 * scale           # the line's steps were off
    np.testing.assert_array_equal(out[mask.repeat(3, 1) > 0.5], line[mask.repeat(3, 1) > 0.5])
    near, mid = np.abs(out - line)[..., 21:24].max(), np.abs(out - line)[..., 33:37].max()
    assert mid < 0.25 * near                                     # the correction fades: mid-gap is the fill


def test_only_the_given_rows_and_whole_gaps_change():
    x, mask = _curves()
    y = (x + 0.5 * (mask < 0.5)).astype(np.float32)             # a fill off by a constant in the gap
    rows = slice(0, 2)
    m = np.broadcast_to(mask, x.shape).copy()
    m[0, 0, 60:65] = 0.0                                         # one row missing for five frames: not a gap
    out = match_edge_velocity(y, x * m, m, 0.3, rows)
    np.testing.assert_array_equal(out[:, 2], y[:, 2])            # row 2 untouched
    np.testing.assert_array_equal(out[..., 55:70], y[..., 55:70])
    assert np.abs(out[:, :2, 20:50] - y[:, :2, 20:50]).max() > 1e-3
    edge = np.ones((1, 1, 80), np.float32)
    edge[..., :10] = 0.0                                         # a gap at the clip's start: no edge before it
    np.testing.assert_array_equal(match_edge_velocity(y, x * edge, edge, 0.3, rows)[..., :10], y[..., :10])


def test_the_shipped_networks_walk_fill_meets_the_keyframes_at_the_walks_speed(cae_fast_walk):
    """CMU 02_01 (a walk the gate hands to the network), a 1 s gap through ``infill``'s path without the motion
    match (which would replace the network's fill here): with the shipped ``model.net_edge_fade`` the joints'
    steps change across the keyframes about as much as the capture's do, much less than the network's own fill,
    and its error does not rise."""
    import dataclasses
    from inbetween_jax.geometry import forward_kinematics
    from inbetween_jax.models.cae.in_file import keyframe_step_change
    from inbetween_jax.models.cae.infer import load, process_motion
    run, motion = cae_fast_walk
    model = load(run)
    assert model.cfg.model.net_edge_fade > 0
    model.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, match_k=0))
    lo = motion.num_frames // 2 - 15
    hi = lo + 30
    truth = forward_kinematics(motion.local_quats, motion.local_pos, motion.skeleton.parents)[1]

    def filled(m):
        res = process_motion(m, motion, [(lo, hi)])
        return res["positions"], res["gaps_ood"][0]["gate_weight"]
    pos, weight = filled(model)
    assert weight > 0.5                                          # the network's fill, not the base
    model.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, net_edge_fade=0.0))
    raw, _ = filled(model)
    capture = keyframe_step_change(truth, lo, hi)
    assert abs(keyframe_step_change(pos, lo, hi) - capture) < 0.5 * abs(keyframe_step_change(raw, lo, hi) - capture)

    def err(p):
        return np.linalg.norm(p[lo:hi] - truth[lo:hi], axis=-1).mean()
    assert err(pos) <= 1.02 * err(raw)
