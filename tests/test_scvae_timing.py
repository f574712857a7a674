"""The S-CVAE sampled mode's timing variants (:func:`inbetween_jax.models.scvae.bank.retimed`): pure maths on a
path whose timing is known in closed form (a straight root line and a constant-rate rotation)."""
from __future__ import annotations

import numpy as np

from inbetween_jax.geometry.quaternion import quat_from_axis_angle
from inbetween_jax.models.scvae.bank import retimed, timing_amplitudes

L, S = 19, 10


def _linear_path():
    """Keyframes and L frames between them moving at a constant rate: the root along x, joint 0 about y."""
    t = np.arange(L + 2) / (L + 1)
    r = np.stack([100 * t, np.zeros_like(t), np.zeros_like(t)], 1)
    q = quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), 1.5 * t)[:, None]           # (L + 2, 1, 4)
    qs = np.broadcast_to(q[None, None, 1:-1], (S, 1, L, 1, 4))
    rs = np.broadcast_to(r[None, None, 1:-1], (S, 1, L, 3))
    return q[None, 0], r[None, 0], q[None, -1], r[None, -1], qs, rs


def test_amplitudes_alternate_and_reach_the_spread():
    a = timing_amplitudes(S, 0.4)
    assert a[0] == 0 and np.all(a[1::2] > 0) and np.all(a[2::2] < 0)
    np.testing.assert_allclose(np.abs(a).max(), 0.4)
    np.testing.assert_allclose(a[1:], [0.08, -0.08, 0.16, -0.16, 0.24, -0.24, 0.32, -0.32, 0.4])
    assert len(set(np.round(a, 9))) == S                                        # no two samples alike


def test_a_constant_rate_path_is_replayed_on_the_warped_clock():
    kq, kr, tq, tr, q, r = _linear_path()
    out_q, out_r = retimed(kq, kr, tq, tr, q, r, 0.6)
    np.testing.assert_allclose(out_q[0], q[0])                                  # sample 0 unchanged
    np.testing.assert_allclose(out_r[0], r[0])
    t = np.arange(1, L + 1) / (L + 1)
    for s, a in enumerate(timing_amplitudes(S, 0.6)):
        u = t + a * np.sin(np.pi * t) / np.pi
        np.testing.assert_allclose(out_r[s, 0, :, 0], 100 * u, atol=1e-9)     # linear in time: exact
        angle = 2 * np.arctan2(np.linalg.norm(out_q[s, 0, :, 0, 1:], axis=-1), np.abs(out_q[s, 0, :, 0, 0]))
        np.testing.assert_allclose(angle, 1.5 * u, atol=1e-5)           # slerp blends near frames linearly
        assert np.all(np.diff(out_r[s, 0, :, 0]) > 0)                          # still moves forward
    early, late = out_r[1, 0, L // 2, 0], out_r[2, 0, L // 2, 0]
    assert early > r[0, 0, L // 2, 0] > late                                    # a > 0 earlier, a < 0 later


def test_zero_spread_changes_nothing():
    kq, kr, tq, tr, q, r = _linear_path()
    out_q, out_r = retimed(kq, kr, tq, tr, q, r, 0.0)
    np.testing.assert_allclose(out_q, q)
    np.testing.assert_allclose(out_r, r)


def test_shipped_samples_are_retimed_between_two_keyframes_only():
    """Through ``infill_between`` with the shipped S-CVAE on a real clip: two keyframes alone get timing variants
    (samples 1-9 move, sample 0 stays); with the frames beside the keyframes known the timing is left alone."""
    import dataclasses
    from inbetween_jax.data import load_motions
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.context import AFTER, BEFORE
    from inbetween_jax.shipped import shipped_run
    trained = infer.load(shipped_run("scvae"))
    assert trained.cfg.model.timing_spread > 0, "the shipped S-CVAE retimes its samples"
    off = dataclasses.replace(trained, cfg=dataclasses.replace(trained.cfg, model=dataclasses.replace(
        trained.cfg.model, timing_spread=0.0)))
    m = load_motions("embedded", "test")[0]
    k0, n = 5, 20
    k1 = k0 + n + 1
    fa = tuple(trained.extra.get("forward_axis") or m.skeleton.forward_axis())

    def keys(sides):
        s = {"q": m.local_quats[k0], "r": m.root_pos[k0], "c": np.zeros(4)}
        e = {"q": m.local_quats[k1], "r": m.root_pos[k1], "c": np.zeros(4)}
        if sides:
            s.update(zip(BEFORE, (m.local_quats[k0 - 1], m.root_pos[k0 - 1], m.local_quats[k0 - 2],
                                  m.root_pos[k0 - 2])))
            e.update(zip(AFTER, (m.local_quats[k1 + 1], m.root_pos[k1 + 1], m.local_quats[k1 + 2],
                                 m.root_pos[k1 + 2])))
        return s, e
    for sides in (False, True):
        on, plain = (infer.infill_between(t, m.skeleton, *keys(sides), n, S, 0, fa) for t in (trained, off))
        np.testing.assert_allclose(on["r"][0], plain["r"][0], atol=1e-6)
        moved = np.abs(on["r"][1:] - plain["r"][1:]).max()
        assert (moved > 1e-3) if not sides else (moved < 1e-6)
        assert (np.abs(on["timing_shift"][1:]).min() > 0) if not sides else not on["timing_shift"].any()
