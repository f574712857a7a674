"""The S-CVAE sampled mode's timing variants (:func:`inbetween_jax.models.scvae.timing.retimed`): pure maths on a
path whose timing is known in closed form (a straight root line and a constant-rate rotation)."""
from __future__ import annotations

import numpy as np
import pytest

from inbetween_jax.geometry.quaternion import quat_from_axis_angle
from inbetween_jax.models.scvae.timing import retimed, timing_amplitudes

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


def test_the_ease_harmonic_is_replayed_exactly_and_held_monotone():
    kq, kr, tq, tr, q, r = _linear_path()
    ease = np.linspace(-0.9, 0.9, S)[:, None]                                   # (S, B = 1)
    out_q, out_r = retimed(kq, kr, tq, tr, q, r, 0.6, ease=ease)
    np.testing.assert_allclose(out_r[0], r[0])                                  # sample 0 unchanged
    t = np.arange(1, L + 1) / (L + 1)
    for s, a in enumerate(timing_amplitudes(S, 0.6)):
        if s == 0:
            continue
        e = np.clip(ease[s, 0], -(0.95 - abs(a)), 0.95 - abs(a))                # held to a monotone clock
        u = t + a * np.sin(np.pi * t) / np.pi + e * np.sin(2 * np.pi * t) / (2 * np.pi)
        np.testing.assert_allclose(out_r[s, 0, :, 0], 100 * u, atol=1e-9)
        assert np.all(np.diff(out_r[s, 0, :, 0]) > 0)
    base_q, base_r = retimed(kq, kr, tq, tr, q, r, 0.6)
    same_q, same_r = retimed(kq, kr, tq, tr, q, r, 0.6, ease=np.zeros((S, 1)))
    np.testing.assert_allclose(same_r, base_r)
    np.testing.assert_allclose(same_q, base_q)


def test_a_spread_per_window_retimes_each_window_as_its_own_spread_would():
    """``spread`` (B,): window b comes out as ``retimed`` at the number ``spread[b]`` gives it alone, here on
    three copies of the constant-rate path at spreads 0 (unchanged), 0.3 and 0.6 (closed form as above)."""
    kq, kr, tq, tr, q, r = _linear_path()
    rep = lambda x, ax: np.repeat(x, 3, axis=ax)                                # noqa: E731
    out_q, out_r = retimed(rep(kq, 0), rep(kr, 0), rep(tq, 0), rep(tr, 0), rep(q, 1), rep(r, 1),
                           np.array([0.0, 0.3, 0.6]))
    np.testing.assert_allclose(out_r[:, 0], r[:, 0])
    np.testing.assert_allclose(out_q[:, 0], q[:, 0])
    t = np.arange(1, L + 1) / (L + 1)
    for b, spread in ((1, 0.3), (2, 0.6)):
        for s, a in enumerate(timing_amplitudes(S, spread)):
            np.testing.assert_allclose(out_r[s, b, :, 0], 100 * (t + a * np.sin(np.pi * t) / np.pi), atol=1e-9)


def test_the_spread_widens_where_the_gate_falls_back():
    """``sample_timing_spread``: ``timing_spread`` where the gate keeps the network (weight 1), the fallback spread
    where it falls back to Slerp (weight 0), linear between; off (0) or without a gate weight: ``timing_spread``."""
    import types
    from inbetween_jax.models.scvae.bank import sample_timing_spread
    cfg = types.SimpleNamespace(timing_spread=0.25, timing_spread_fallback=0.45)
    np.testing.assert_allclose(sample_timing_spread(cfg, np.array([1.0, 0.0, 0.5, 1.3])), [0.25, 0.45, 0.35, 0.25])
    assert sample_timing_spread(cfg, 0.0) == pytest.approx(0.45) and sample_timing_spread(cfg) == 0.25
    assert sample_timing_spread(types.SimpleNamespace(timing_spread=0.25, timing_spread_fallback=0.0), 0.0) == 0.25


def test_zero_spread_changes_nothing():
    kq, kr, tq, tr, q, r = _linear_path()
    out_q, out_r = retimed(kq, kr, tq, tr, q, r, 0.0)
    np.testing.assert_allclose(out_q, q)
    np.testing.assert_allclose(out_r, r)


def test_shipped_samples_are_retimed_more_between_two_keyframes_than_inside_a_clip():
    """Through ``infill_between`` with the shipped S-CVAE on a real clip: samples 1-9 get timing variants (sample 0
    stays), at ``timing_spread`` between two keyframes alone (up to ``timing_spread_fallback`` as the gate falls
    back to Slerp) and at the smaller ``timing_spread_in_clip`` where the frames beside the keyframes are known
    (they pin the timing); with the spreads 0 nothing is retimed."""
    import dataclasses
    from inbetween_jax.data import load_motions
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.scvae.bank import sample_timing_spread
    from inbetween_jax.models.scvae.context import AFTER, BEFORE
    from inbetween_jax.shipped import shipped_run
    trained = infer.load(shipped_run("scvae"))
    mc = trained.cfg.model
    assert mc.timing_spread > mc.timing_spread_in_clip > 0, "the shipped S-CVAE retimes its samples, less in a clip"
    off = dataclasses.replace(trained, cfg=dataclasses.replace(trained.cfg, model=dataclasses.replace(
        mc, timing_spread=0.0, timing_spread_in_clip=0.0, timing_spread_fallback=0.0)))
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
        assert on["context"] == ("none" if not sides else "both sides")
        # between two keyframes the spread widens as the gate falls back (sample_timing_spread); in a clip fixed
        spread = mc.timing_spread_in_clip if sides else sample_timing_spread(mc, on["gate_weight"])
        assert sides or mc.timing_spread <= spread <= mc.timing_spread_fallback
        np.testing.assert_allclose(on["r"][0], plain["r"][0], atol=1e-6)
        assert np.abs(on["q"][1:] - plain["q"][1:]).max() > 1e-3                     # samples 1-9 retimed
        np.testing.assert_allclose(np.abs(on["timing_by_part"]).max(), spread)
        assert np.abs(on["timing_shift"][1:]).min() > 0 and not on["timing_shift"][0]
        assert not plain["timing_by_part"].any()


# ---- part-wise timing (model.timing_parts) ----

def test_part_amplitudes_split_the_samples_between_whole_and_part_wise_timing():
    from inbetween_jax.models.scvae.timing import PARTS, part_amplitudes
    a = part_amplitudes(S, 0.3)
    assert a.shape == (S, len(PARTS)) and not a[0].any()                        # sample 0 is the fill
    whole, parts = a[1:5], a[5:]
    np.testing.assert_allclose(whole, np.repeat(timing_amplitudes(5, 0.3)[1:, None], len(PARTS), 1))
    assert not parts[:, 0].any()                                                # part-wise: the torso keeps time
    assert all(row.max() > 0 > row.min() for row in parts)                      # one part earlier, another later
    np.testing.assert_allclose(np.abs(parts).max(), 0.3)
    assert len({tuple(np.round(r, 9)) for r in a}) == S                         # no two samples alike
    np.testing.assert_allclose(part_amplitudes(S, 0.3, parts=False),
                               np.repeat(timing_amplitudes(S, 0.3)[:, None], len(PARTS), 1))


def test_each_part_is_replayed_on_its_own_clock():
    """Five joints, one per part, each turning at a constant rate; the root moving along x: every joint's angle
    follows its own part's warped clock, the root the torso's."""
    from inbetween_jax.models.scvae.timing import part_amplitudes, retimed
    t = np.arange(L + 2) / (L + 1)
    q = np.stack([quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), (0.5 + 0.25 * j) * t) for j in range(5)], 1)
    r = np.stack([100 * t, np.zeros_like(t), np.zeros_like(t)], 1)
    qs = np.broadcast_to(q[None, None, 1:-1], (S, 1, L, 5, 4))
    rs = np.broadcast_to(r[None, None, 1:-1], (S, 1, L, 3))
    out_q, out_r = retimed(q[None, 0], r[None, 0], q[None, -1], r[None, -1], qs, rs, 0.5, parts=np.arange(5))
    np.testing.assert_allclose(out_q[0], qs[0])
    tt = t[1:-1]
    for s, amps in enumerate(part_amplitudes(S, 0.5)):
        for j in range(5):
            u = tt + amps[j] * np.sin(np.pi * tt) / np.pi
            angle = 2 * np.arctan2(np.linalg.norm(out_q[s, 0, :, j, 1:], axis=-1), np.abs(out_q[s, 0, :, j, 0]))
            np.testing.assert_allclose(angle, (0.5 + 0.25 * j) * u, atol=1e-5)
        np.testing.assert_allclose(out_r[s, 0, :, 0], 100 * (tt + amps[0] * np.sin(np.pi * tt) / np.pi), atol=1e-9)


def test_body_parts_on_three_rigs():
    """The 21-joint CMU rig of the shipped weights, the raw 43-joint CMU rig (fingers, eyes) and LaFAN1's: feet in
    their own side's leg, each arm's mirror twin in the other arm, the root and head in the torso."""
    import os
    from conftest import CLIP_A, LAFAN1_DIR, SHARED_DATA
    from inbetween_jax.data.bvh import read_bvh
    from inbetween_jax.models.scvae.timing import PARTS, body_parts
    files = [CLIP_A, os.path.join(SHARED_DATA, "cmu_bvh", "02_01.bvh"),
             os.path.join(LAFAN1_DIR, "dance1_subject1.bvh")]
    files = [f for f in files if os.path.exists(f)]
    assert CLIP_A in files
    for f in files:
        sk = read_bvh(f, 0, 2).skeleton
        parts = body_parts(sk)
        names = [n.lower() for n in sk.names]
        la, _, ra, _ = sk.foot_joints()
        assert PARTS[parts[la]] == "left leg" and PARTS[parts[ra]] == "right leg", f
        assert parts[0] == 0 and parts[names.index("head")] == 0, f
        twin = sk.mirror_map()
        arms = [j for j in range(len(parts)) if PARTS[parts[j]].endswith("arm")]
        assert len(arms) >= 8, f                                                # collar / shoulder .. hand, both
        for j in arms:
            assert {PARTS[parts[j]], PARTS[parts[twin[j]]]} == {"left arm", "right arm"}, (f, sk.names[j])
        hand = next(j for j, n in enumerate(names) if n in ("lhand", "lefthand"))
        assert PARTS[parts[hand]] == "left arm", f


@pytest.mark.slow
def test_bench_writes_the_sampled_mode_rows_two_keyframes_and_inside_a_clip(tmp_path):
    """The S-CVAE bench section on the shipped weights (embedded test windows): bench.json's samples table holds
    the sampled mode between two keyframes and inside a clip, beside the fills they start from; the samples are
    apart where the fills' ten samples are not, and sample 0 keeps their accuracy within the 3 % rule's reach."""
    from inbetween_jax.models.scvae.bench import run
    from inbetween_jax.shipped import shipped_run
    out = run("embedded", str(tmp_path), shipped_run("scvae").run_dir, quick=True)
    rows = [r for r in out["rows"] if r.get("table") == "samples"]
    preset = shipped_run("scvae").preset

    def get(variant, frames, metric):
        hit = [r["value"] for r in rows if r.get("variant") == variant and r.get("frames") == frames
               and r.get("metric") == metric]
        assert len(hit) == 1, (variant, frames, metric)
        return hit[0]
    for n in (10, 30, 50):
        for fill, sampled in ((preset, f"{preset}, sampled mode"),
                              (f"{preset}, inside a clip", f"{preset}, sampled mode, inside a clip")):
            assert get(sampled, n, "pairwise_cm") > 5 * get(fill, n, "pairwise_cm")
            assert get(sampled, n, "best_cm") < get(fill, n, "best_cm")
            assert get(sampled, n, "mean_cm") < 1.1 * get(fill, n, "mean_cm")
