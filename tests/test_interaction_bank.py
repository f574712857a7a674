"""The interaction model's motion bank (:mod:`inbetween_jax.models.interaction.bank`): nearest-neighbour
in-betweens warped onto the query's ends, motion texture checked against scipy's Gaussian filter, the switches,
and the bank file, on real capture (constructed pairs of the shipped CMU clips)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from inbetween_jax.errors import UserError
from inbetween_jax.models.interaction.bank import (FADE, SWITCHES, MotionBank, apply_bank,
                                                   arrival_gaps, bank_enabled, foot_indices, knn_inbetween, texture)
from inbetween_jax.models.interaction.config import ModelConfig, get_config
from inbetween_jax.models.interaction.infer import load_bank
from inbetween_jax.shipped import INFERENCE_SWITCHES
from inbetween_jax.train.run import RunError

N_IN, GAP = 20, 30


@pytest.fixture(scope="module")
def bank(pair_train):
    return MotionBank.from_pairs(pair_train, 0.01, stride=3)


def _query(bank, i):
    x = bank.gather(N_IN, GAP, [i])
    return x[:, :, :N_IN], x[:, :, -1], x


def test_knn_of_a_bank_window_is_that_window(bank):
    n = len(bank.index(N_IN, GAP))
    assert n > 20 and bank.gather(N_IN, GAP, [[0, 1]]).shape[:4] == (1, 2, 2, N_IN + GAP + 1)
    longest = bank.max_gap(N_IN)
    assert len(bank.index(N_IN, longest)) >= 1
    with pytest.raises(UserError, match="long enough"):
        bank.index(N_IN, longest + 1)
    for i in (0, n // 2, n - 1):
        ctx, kp, win = _query(bank, i)
        np.testing.assert_allclose(knn_inbetween(bank, ctx, kp, GAP, 1), win[:, :, N_IN:N_IN + GAP], atol=1e-5)


def test_knn_warp_moves_each_frame_by_its_share_of_the_end_offset(bank):
    ctx, kp, win = _query(bank, 7)
    delta = np.zeros(9, np.float32)
    delta[:3] = (0.002, -0.001, 0.003)                 # 2-3 mm: small enough that the nearest window stays the same
    moved = knn_inbetween(bank, ctx, kp + delta, GAP, 1)
    share = (np.arange(1, GAP + 1) / (GAP + 1))[None, None, :, None, None]
    np.testing.assert_allclose(moved, win[:, :, N_IN:N_IN + GAP] + share * delta, atol=1e-5)


def test_texture_is_the_nearest_windows_high_band_faded_at_the_ends(bank):
    sigma = 4.0
    ctx, kp, win = _query(bank, 11)
    band = texture(bank, ctx, kp, GAP, sigma)
    pos = win[..., :3].astype(np.float64)
    ref = (pos - gaussian_filter1d(pos, sigma, axis=2, mode="nearest", truncate=3.0))[:, :, N_IN:N_IN + GAP]
    fade = np.ones(GAP)
    fade[:FADE] = fade[-FADE:][::-1] = np.arange(1, FADE + 1) / (FADE + 1)
    np.testing.assert_allclose(band[..., :3], ref * fade[None, None, :, None, None], atol=1e-5)
    assert np.all(band[..., 3:] == 0)
    assert np.abs(band[..., :3]).max() > 1e-3                        # real capture has a high band (> 1 mm)


def test_apply_bank_switches(bank, pair_windows):
    ctx, kp = pair_windows["x"][:, :, :N_IN], pair_windows["keypose"]
    B = len(ctx)
    frames = np.random.default_rng(0).normal(size=(2, B, 2, 40) + ctx.shape[3:]).astype(np.float32)
    off = ModelConfig()
    assert not bank_enabled(off)
    np.testing.assert_array_equal(apply_bank(bank, off, frames, ctx, kp, np.full(B, GAP)), frames)
    only_bank = dataclasses.replace(off, bank_k=3, bank_weight=1.0)
    out = apply_bank(bank, only_bank, frames, ctx, kp, np.full(B, GAP))
    near = knn_inbetween(bank, ctx, kp, GAP, 3)
    np.testing.assert_allclose(out[:, :, :, :GAP], np.broadcast_to(near, out[:, :, :, :GAP].shape), atol=1e-6)
    np.testing.assert_array_equal(out[:, :, :, GAP:], frames[:, :, :, GAP:])      # past the gap: untouched
    half = apply_bank(bank, dataclasses.replace(only_bank, bank_weight=0.5, texture_sigma=4.0, texture_gain=2.0),
                      frames, ctx, kp, np.full(B, GAP))
    expect = 0.5 * frames[:, :, :, :GAP] + 0.5 * near + 2.0 * texture(bank, ctx, kp, GAP, 4.0)
    np.testing.assert_allclose(half[:, :, :, :GAP], expect, atol=1e-5)


def test_sampled_mode_gives_each_sample_its_own_captured_window(bank, pair_windows):
    """``model.bank_sample_weight``: sample 0 is the deterministic fill; sample s >= 1 blends in the s-th nearest
    window alone (warped), with that window's texture on the rest; one sample is never sampled."""
    from inbetween_jax.models.interaction.bank import _nearest
    ctx, kp = pair_windows["x"][:, :, :N_IN], pair_windows["keypose"]
    B = len(ctx)
    frames = np.random.default_rng(1).normal(size=(4, B, 2, 40) + ctx.shape[3:]).astype(np.float32)
    det = dataclasses.replace(ModelConfig(), bank_k=3, bank_weight=0.25)
    sampled = dataclasses.replace(det, bank_sample_weight=1.0)
    assert bank_enabled(dataclasses.replace(ModelConfig(), bank_sample_weight=0.5))
    ref, out = (apply_bank(bank, c, frames, ctx, kp, np.full(B, GAP)) for c in (det, sampled))
    np.testing.assert_allclose(out[0], ref[0], atol=1e-6)
    near = _nearest(bank, ctx, kp, GAP, 3)
    for s in (1, 2, 3):                           # weight 1: the (s-1)-th nearest window itself, warped
        np.testing.assert_allclose(out[s, :, :, :GAP], knn_inbetween(bank, ctx, kp, GAP, s)[:, :, :GAP] * s -
                                   (knn_inbetween(bank, ctx, kp, GAP, s - 1) * (s - 1) if s > 1 else 0),
                                   atol=1e-4)
    assert near.shape[1] == 3 and np.abs(out[1] - out[2]).mean() > 1e-3          # the samples differ
    half = apply_bank(bank, dataclasses.replace(det, bank_sample_weight=0.5, texture_sigma=4.0), frames, ctx, kp,
                      np.full(B, GAP))
    one = knn_inbetween(bank, ctx, kp, GAP, 1)
    band = texture(bank, ctx, kp, GAP, 4.0)
    np.testing.assert_allclose(half[1, :, :, :GAP], 0.5 * frames[1, :, :, :GAP] + 0.5 * one + 0.5 * band, atol=1e-5)
    single = apply_bank(bank, sampled, frames[:1], ctx, kp, np.full(B, GAP))
    np.testing.assert_allclose(single[0], ref[0], atol=1e-6)


def _window_rel(bank, i):
    """Window i's keyframe-space maps (rel_R (1, 2, 3, 3), rel_t (1, 2, 3) in model units)."""
    from inbetween_jax.models.interaction.features import keyframe_sample
    take, s = bank._starts(N_IN, GAP)[i]
    b = keyframe_sample(bank.takes[take], s, N_IN + GAP + 1, N_IN + GAP, bank.forward_axis)
    return b["rel_R"][None].astype(np.float32), (b["rel_t"] * bank.pos_scale)[None].astype(np.float32)


def test_pair_features_place_the_partner_and_steer_the_match(bank):
    """``model.bank_pair_weight``: the pair features are the partner's floor distance and relative heading at the
    keyframe (checked against the raw take); with weight 0 the match ignores them, with a large weight it picks the
    window whose pair placement is nearest the query's (brute force)."""
    from inbetween_jax.models.interaction.bank import _nearest, match_features
    from inbetween_jax.models.interaction.features import facing_yaw
    pairs = bank.pair_index(N_IN, GAP)
    n = len(pairs)
    for i in (0, n // 3, n - 1):
        take, s = bank._starts(N_IN, GAP)[i]
        key = bank.takes[take][:, s + N_IN + GAP, 0]                                  # (2, 9) roots, file units
        floor = np.hypot(*(key[1, [0, 2]] - key[0, [0, 2]])) * bank.pos_scale
        turn = np.subtract(*facing_yaw(key[::-1], bank.forward_axis))                 # B's heading minus A's
        np.testing.assert_allclose(np.hypot(*pairs[i, :2]), floor, rtol=1e-4, atol=1e-6)
        np.testing.assert_allclose([pairs[i, 2], abs(pairs[i, 3])], [np.cos(turn), abs(np.sin(turn))], atol=1e-4)
    far = int(np.argmax(((pairs - pairs[5]) ** 2).sum(1)))                         # another pair placement
    ctx, kp, win = _query(bank, 5)
    rel = _window_rel(bank, far)
    np.testing.assert_array_equal(_nearest(bank, ctx, kp, GAP, 1, rel, 0.0)[:, 0], win)
    d2 = ((match_features(ctx, kp) - bank.index(N_IN, GAP)) ** 2).sum(1) + 1e6 * ((pairs - pairs[far]) ** 2).sum(1)
    np.testing.assert_allclose(_nearest(bank, ctx, kp, GAP, 1, rel, 1e3)[:, 0], bank.gather(N_IN, GAP,
                               [int(np.argmin(d2))]), atol=1e-6)
    assert int(np.argmin(d2)) != 5
    with pytest.raises(ValueError, match="rel_R"):
        apply_bank(bank, dataclasses.replace(ModelConfig(), bank_k=1, bank_weight=0.5, bank_pair_weight=1.0),
                   np.zeros((1, 1, 2, GAP) + ctx.shape[3:], np.float32), ctx, kp, np.full(1, GAP))


def test_bank_file_round_trip_and_errors(bank, tmp_path):
    path = str(tmp_path / "bank.npz")
    bank.save(path)
    back = MotionBank.load(path)
    assert back.names == bank.names and back.stride == bank.stride and back.pos_scale == bank.pos_scale
    for a, b in zip(back.takes, bank.takes):
        np.testing.assert_array_equal(a, b)
    bad = tmp_path / "junk.npz"
    bad.write_bytes(b"not an npz")
    with pytest.raises(UserError, match="junk.npz"):
        MotionBank.load(str(bad))
    bad.write_bytes(open(path, "rb").read()[:200])          # cut short: not a zip any more
    with pytest.raises(UserError, match="junk.npz: not a readable motion bank"):
        MotionBank.load(str(bad))
    cfg = get_config("tiny")
    on = dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, texture_sigma=4.0))
    with pytest.raises(RunError, match="needs bank.npz, which is missing"):
        load_bank(str(tmp_path / "empty"), on, bank.takes[0].shape[2])
    with pytest.raises(RunError, match="joints"):
        load_bank(str(tmp_path), on, bank.takes[0].shape[2] + 1)
    assert load_bank(str(tmp_path / "empty"), cfg, 3) is None              # switches off: no bank needed
    assert set(SWITCHES) <= set(INFERENCE_SWITCHES["interaction"])


def test_bank_keeps_the_match_features_of_the_last_used_lengths_only(bank, monkeypatch):
    from inbetween_jax.models.interaction import bank as bank_module
    monkeypatch.setattr(bank_module, "CACHED_LENGTHS", 2)
    fresh = MotionBank(bank.takes, bank.names, bank.forward_axis, bank.pos_scale, bank.stride)
    first = fresh.index(N_IN, 10)
    fresh.index(N_IN, 12)
    assert fresh.index(N_IN, 10) is first                                    # reused, and now the newest
    fresh.index(N_IN, 14)                                                    # drops 12, the least recently used
    assert sorted(g for _, g in fresh._cache) == [10, 14]
    np.testing.assert_array_equal(fresh.index(N_IN, 12), bank.index(N_IN, 12))


def test_texture_never_takes_a_foot_below_the_skating_height(bank, pair_windows):
    ctx, kp = pair_windows["x"][:, :, :N_IN], pair_windows["keypose"]
    B = len(ctx)
    assert foot_indices(None) == ()
    feet = (3, 7, 9)                                                          # three joints stand in for feet
    frames = np.zeros((1, B, 2, GAP) + ctx.shape[3:], np.float32)
    frames[..., 3, 1] = 0.02                                                  # 2 cm: within the skating height
    frames[..., 7, 1] = 0.04                                                  # 4 cm: between H and 2 H
    frames[..., 9, 1] = 0.50                                                  # 50 cm: far above the floor
    cfg = dataclasses.replace(ModelConfig(), texture_sigma=2.0, texture_gain=1.0)
    added = apply_bank(bank, cfg, frames, ctx, kp, np.full(B, GAP), feet) - frames
    band = np.broadcast_to(texture(bank, ctx, kp, GAP, 2.0)[None], added.shape)
    np.testing.assert_allclose(added[..., 3, :], 0.0, atol=1e-7)
    np.testing.assert_allclose(added[..., 9, :], band[..., 9, :], atol=1e-6)
    np.testing.assert_allclose(added[..., 0, :], band[..., 0, :], atol=1e-6)  # not a foot: full texture
    assert np.all(frames[..., 7, 1] + added[..., 7, 1] >= 0.025 - 1e-6)
    big = (np.abs(band[..., 7, :3]) > 1e-3).all(-1)                             # frames with > 1 mm on every axis
    w = added[..., 7, :3][big] / band[..., 7, :3][big]                         # one weight per frame, in [0, 1]
    assert len(w) > 10 and np.allclose(w, w[:, :1], atol=1e-3) and w.min() >= -1e-6 and w.max() <= 1 + 1e-6
    assert 0 < w.mean() < 1
    free = apply_bank(bank, cfg, frames, ctx, kp, np.full(B, GAP)) - frames  # no feet named: texture everywhere
    np.testing.assert_allclose(free, band, atol=1e-6)


def test_arrival_gap_is_the_first_frame_with_both_characters_within_the_threshold(bank):
    """A rollout (real keyposes) held 20 cm off its keyposes until frame g and on them from there arrives after g
    frames (threshold 15 cm); 14.9 cm off counts as arrived and 15.1 cm does not, for either character; one that
    never arrives takes all its frames; centimetre units (``pos_scale`` 1) give the same gaps."""
    _, kp, _ = _query(bank, 5)                                               # (1, 2, J, 9) in metres
    F = 40
    held = np.repeat(kp[:, :, None], F, 2)                                   # (1, 2, F, J, 9) on the keyposes
    rows, expect = [], []
    for g in (3, 17, 39):
        r = held.copy()
        r[:, :, :g, :, 0] += 0.2
        rows.append(r)
        expect.append(g)
    for cm, arrived in ((14.9, True), (15.1, False)):
        for who in (0, 1):
            r = held.copy()
            r[:, who, :, :, 2] += cm / 100
            rows.append(r)
            expect.append(0 if arrived else F)
    never = held.copy()
    never[..., 0] += 0.5
    rows.append(never)
    expect.append(F)
    frames = np.concatenate(rows)
    keys = np.repeat(kp, len(rows), 0)
    np.testing.assert_array_equal(arrival_gaps(frames, keys, 0.15, 0.01, lo=0), expect)
    np.testing.assert_array_equal(arrival_gaps(frames, keys, 0.15, 0.01), np.maximum(expect, 1))
    cm = frames.copy()
    cm[..., :3] *= 100
    np.testing.assert_array_equal(arrival_gaps(cm, keys * np.array([100] * 3 + [1] * 6, np.float32), 0.15, 1.0,
                                               lo=0), expect)
