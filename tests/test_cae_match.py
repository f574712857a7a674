"""The CAE's motion matching inside a file (:mod:`inbetween_jax.models.cae.bank`) on real capture: a gap cut from
a bank clip finds that clip and gives its frames back; tempo and mirror copies; the gate's weight; the bank file's
errors; and the shipped weights' wiring through ``process_motion`` on a validation subject's walk."""
from __future__ import annotations

import dataclasses
import os
import shutil

import numpy as np
import pytest

from inbetween_jax.data import load_motions
from inbetween_jax.models.cae.bank import (MARGIN, MatchBank, _played_at, gate_distance, match_candidates, match_gap,
                                           match_weight, speed_beside)
from inbetween_jax.models.cae.features import body_frame_features, mirror_rows
from inbetween_jax.models.scvae.bank import TransitionBank
from inbetween_jax.train.run import RunError


@pytest.fixture(scope="module")
def shipped():
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.shipped import shipped_run
    return load(shipped_run("cae"))


@pytest.fixture(scope="module")
def motions():
    return load_motions("embedded", "train")


def _query(model, motion, a, b):
    feats = body_frame_features(motion)
    x = model.normalizer(feats.features).T.astype(np.float32)
    mask = np.ones_like(x)
    mask[:, a:b] = 0.0
    return x, x * mask, feats.ref, feats.yaw


def test_played_at_resamples_time_and_scales_velocities():
    t = np.arange(41, dtype=np.float64)
    feats = np.stack([t, 2 * t, np.ones(41), np.ones(41), np.full(41, 3.0)], 1)   # two "position" rows, then velocities
    ref, yaw = np.stack([t, -t], 1), 0.1 * t
    f, r, y = _played_at(feats, ref, yaw, 2.0)
    assert len(f) == 21
    np.testing.assert_allclose(f[:, 1], 4 * np.arange(21))                # every second frame
    np.testing.assert_allclose(f[:, -3:], [[2.0, 2.0, 6.0]] * 21)         # per-frame velocities twice as large
    np.testing.assert_allclose(r[:, 0], 2 * np.arange(21))
    np.testing.assert_allclose(y, 0.2 * np.arange(21))
    same = _played_at(feats, ref, yaw, 1.0)
    assert same[0] is feats


def test_match_weight_ramp():
    assert match_weight(0.1, 0.2, 0.4) == 1.0
    assert match_weight(0.3, 0.2, 0.4) == pytest.approx(0.5)
    assert match_weight(0.5, 0.2, 0.4) == 0.0
    assert match_weight(float("inf"), 0.2, 0.4) == 0.0


def test_speed_beside_reads_the_known_frames_on_each_side_only():
    """A root walking 2 cm per frame before the gap and 4 after it, with anything inside the gap: 3 cm per frame;
    the gate reads the distance over 1 + speed / scale (unchanged with scale 0)."""
    a, b = 20, 40
    steps = np.where(np.arange(60) < a, 2.0, 4.0)
    track = np.stack([np.cumsum(steps), np.zeros(60)], 1)
    track[a:b] = np.random.default_rng(0).normal(0, 50, (b - a, 2))           # broken capture in the gap
    assert speed_beside(track, a, b) == pytest.approx(3.0)
    assert speed_beside(track[:, ::-1] * 0.0, a, b) == 0.0                         # standing still
    assert gate_distance(0.06, 3.0, 1.0) == pytest.approx(0.015)
    assert gate_distance(0.06, 3.0, 0.0) == 0.06


def test_shipped_gate_lets_a_walk_match_lie_farther_than_a_standing_one(shipped):
    """The shipped gate reads the distance relative to the speed beside the gap: the same match distance opens
    the gate beside a walk (3 cm per frame) and keeps it shut beside a body standing still."""
    mc = shipped.cfg.model
    assert mc.match_speed_scale > 0
    d = 0.5 * (mc.match_lo + mc.match_hi) * (1 + 3.0 / mc.match_speed_scale)     # halfway up the ramp at 3 cm
    assert match_weight(gate_distance(d, 3.0, mc.match_speed_scale), mc.match_lo, mc.match_hi) == pytest.approx(0.5)
    assert match_weight(gate_distance(d, 0.0, mc.match_speed_scale), mc.match_lo, mc.match_hi) == 0.0


def test_a_gap_cut_from_a_bank_clip_gets_that_clip_back(shipped, motions):
    m = motions[0]
    tb = TransitionBank.from_motions([m], m.skeleton.forward_axis())
    bank = MatchBank.from_transition_bank(tb, shipped.skeleton, shipped.normalizer, shipped.num_joints)
    a = MARGIN + 2 * 10                                  # a candidate start (stride 2)
    b = a + 24
    x, xm, ref, yaw = _query(shipped, m, a, b)
    fill, dist = match_gap(bank, xm, ref, yaw, a, b, k=1)
    assert dist < 1e-6
    np.testing.assert_allclose(fill, x[:, a:b], atol=2e-3)
    # a gap whose context is not there (too near the clip's start) is not matched
    assert match_gap(bank, xm, ref, yaw, MARGIN - 1, MARGIN + 20, k=1) == (None, float("inf"))
    # a bank of two files with the clip's own file excluded (leaving a subject out): the other file's windows
    two = MatchBank.from_transition_bank(TransitionBank.from_motions([m, motions[2]], m.skeleton.forward_axis()),
                                         shipped.skeleton, shipped.normalizer, shipped.num_joints)
    assert two.names == [os.path.basename(str(x.source)) for x in (m, motions[2])]
    _, d_own = match_gap(two, xm, ref, yaw, a, b, k=1)
    other, d_other = match_gap(two, xm, ref, yaw, a, b, k=1, exclude=np.array([True, False]))
    assert d_own < 1e-6 < d_other and np.abs(other - x[:, a:b]).max() > 2e-3
    assert match_gap(two, xm, ref, yaw, a, b, k=1, exclude=np.array([True, True])) == (None, float("inf"))
    # the k candidates, nearest first; the matched fill is their mean, and an excluded clip's windows never
    # enter it, even when k asks for more windows than the other clips hold
    fills, d = match_candidates(two, xm, ref, yaw, a, b, k=4)
    assert fills.shape == (4, x.shape[0], b - a) and np.all(np.diff(d) >= 0) and d[0] < 1e-6
    np.testing.assert_allclose(match_gap(two, xm, ref, yaw, a, b, k=4)[0], fills.mean(0), atol=1e-6)
    where = two.index(b - a)[3]                                       # (N, 2): clip, start of every window
    n_other = int(np.sum(where[:, 0] == 1))
    fills, d = match_candidates(two, xm, ref, yaw, a, b, k=n_other + 5, exclude=np.array([True, False]))
    assert len(fills) == n_other and np.isfinite(d).all() and d[0] == d_other


def test_a_bank_of_features_played_at_a_tempo_matches_that_tempo(shipped, motions):
    """``MatchBank.from_features`` (a file's own frames as a bank): the same clips as the transition-bank route at
    tempo 1, and a gap of the clip played slower finds the slowed copy, not the clip at its own pace."""
    m = motions[0]
    feats = body_frame_features(m)
    item = (feats.features, feats.ref, feats.yaw, "own")
    via_bank = MatchBank.from_transition_bank(TransitionBank.from_motions([m], m.skeleton.forward_axis()),
                                              shipped.skeleton, shipped.normalizer, shipped.num_joints)
    own = MatchBank.from_features([item], shipped.normalizer)
    np.testing.assert_allclose(own.clips[0], via_bank.clips[0], atol=1e-4)
    f, ref, yaw = _played_at(feats.features.astype(np.float64), feats.ref, feats.yaw, 0.8)
    x = shipped.normalizer(f.astype(np.float32)).T.astype(np.float32)
    a, b = MARGIN + 30, MARGIN + 60
    mask = np.ones_like(x)
    mask[:, a:b] = 0.0
    both = MatchBank.from_features([item], shipped.normalizer, tempos=(1.0, 0.8))
    assert len(both.clips) == 2 and both.clips[1].shape[1] == len(f)
    fill, dist = match_gap(both, x * mask, ref, yaw, a, b, k=1)
    assert dist < 1e-6
    np.testing.assert_allclose(fill, x[:, a:b], atol=2e-3)
    assert match_gap(own, x * mask, ref, yaw, a, b, k=1)[1] > 1e-3
    assert MatchBank.from_features([(feats.features[:2 * MARGIN], feats.ref[:2 * MARGIN],
                                     feats.yaw[:2 * MARGIN], "short")], shipped.normalizer).clips == []


def test_mirror_copy_matches_the_mirrored_motion(shipped, motions):
    m = motions[1]
    tb = TransitionBank.from_motions([m], m.skeleton.forward_axis())
    plain = MatchBank.from_transition_bank(tb, shipped.skeleton, shipped.normalizer, shipped.num_joints)
    both = MatchBank.from_transition_bank(tb, shipped.skeleton, shipped.normalizer, shipped.num_joints, mirror=True)
    assert len(both.clips) == 2 * len(plain.clips)
    perm, sign = mirror_rows(shipped.skeleton)
    raw = shipped.normalizer.inverse(both.clips[0].T.astype(np.float64))
    mirrored = shipped.normalizer.inverse(both.clips[1].T.astype(np.float64))
    np.testing.assert_allclose(mirrored, sign[None] * raw[:, perm], atol=1e-3)
    # the mirror's gap (same frames) finds the mirror copy, not the original
    a, b = MARGIN + 10, MARGIN + 40
    x = both.clips[1]
    mask = np.ones_like(x)
    mask[:, a:b] = 0
    fill, dist = match_gap(both, x * mask, *both.tracks[1], a, b, k=1)
    assert dist < 1e-6
    np.testing.assert_allclose(fill, x[:, a:b], atol=2e-3)
    fill_plain, dist_plain = match_gap(plain, x * mask, *both.tracks[1], a, b, k=1)
    assert dist_plain > 100 * max(dist, 1e-9)


def test_shipped_walk_gap_follows_a_training_walk(shipped):
    """A validation subject's walk (never in the bank): the matched fill is used, is recorded per gap and is nearer
    the capture than the fill without it; its count of foot lift-offs is also nearer the capture's than that fill's
    (the network's own fill lifts the feet more often here)."""
    from inbetween_jax.metrics.steps import lift_offs
    from inbetween_jax.models.cae.infer import process_motion
    assert shipped.match is not None and shipped.cfg.model.match_k > 0, "the shipped CAE matches gaps"
    walk = [m for m in load_motions("cmu", "val-subjects") if os.path.basename(str(m.source)) == "12_01.bvh"][0]
    gap = (30, 60)                  # at (40, 70) the network's edge-matched fill ties the match (2026-12-07)
    res = process_motion(shipped, walk, [gap])
    row = res["gaps_ood"][0]
    assert row["gap"] == list(gap) and row["match_weight"] > 0.5 and row["match_distance"] < shipped.cfg.model.match_lo
    off = dataclasses.replace(shipped.cfg, model=dataclasses.replace(shipped.cfg.model, match_k=0))
    plain = process_motion(_with_cfg(shipped, off), walk, [gap])
    feet = shipped.skeleton.foot_joints()
    span = slice(gap[0] - 1, gap[1] + 1)
    steps = [float(lift_offs(r["positions"][span], (feet[0], feet[2]))) for r in (res, plain)]
    captured = float(lift_offs(walk.global_positions()[span], (feet[0], feet[2])))
    assert steps[0] >= 1 and abs(steps[0] - captured) < abs(steps[1] - captured)
    truth = walk.global_positions()[gap[0]:gap[1]]
    err = [np.linalg.norm(r["positions"][gap[0]:gap[1]] - truth, axis=-1).mean() for r in (res, plain)]
    assert err[0] < err[1]


def _with_cfg(model, cfg):
    import copy
    out = copy.copy(model)
    out.cfg = cfg
    return out


def test_match_without_a_bank_file_is_one_line(tmp_path):
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.shipped import shipped_dir
    from inbetween_jax.train.run import load_run
    src = shipped_dir("cae")
    dst = tmp_path / "cae"
    shutil.copytree(src, dst)
    if (dst / "bank.npz").exists():
        os.remove(dst / "bank.npz")
    import json
    meta = json.loads((dst / "run.json").read_text())
    meta["config"]["model"]["match_k"] = 4
    (dst / "run.json").write_text(json.dumps(meta))
    with pytest.raises(RunError, match="model.match_k needs bank.npz"):
        load(load_run(str(dst)))


def test_build_bank_shares_the_scvae_bank_beside_it(tmp_path):
    """The shipped CAE's bank is byte-identical to the S-CVAE's beside it: build-bank records it instead of storing
    it twice, and the CAE loads it from there; alone, the folder gets its own file."""
    import json
    from inbetween_jax.banks import write_bank
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.shipped import shipped_dir
    from inbetween_jax.train.run import load_run
    root = tmp_path / "w"
    for m in ("cae", "scvae"):
        shutil.copytree(shipped_dir(m), root / m)
    out = write_bank(str(root / "cae"), switches=["model.match_k=8"])
    assert not (root / "cae" / "bank.npz").exists() and out["path"] == str(root / "scvae" / "bank.npz")
    meta = json.loads((root / "cae" / "run.json").read_text())
    assert meta["bank"]["shared_with"] == "scvae"
    keys = [item.split("=", 1)[0] for item in meta["shipped"]["inference"]]
    assert "model.match_k=8" in meta["shipped"]["inference"] and keys.count("model.match_k") == 1
    model = load(load_run(str(root / "cae")))
    assert model.match is not None and len(model.match.clips) == 171
    alone = tmp_path / "alone"
    shutil.copytree(root / "cae", alone / "cae")
    write_bank(str(alone / "cae"))
    assert (alone / "cae" / "bank.npz").exists()
    assert "shared_with" not in json.loads((alone / "cae" / "run.json").read_text())["bank"]


def test_the_bank_keeps_a_few_gap_lengths_only(shipped, motions):
    from inbetween_jax.models.cae.bank import CACHED_LENGTHS
    m = motions[0]
    tb = TransitionBank.from_motions([m], m.skeleton.forward_axis())
    bank = MatchBank.from_transition_bank(tb, shipped.skeleton, shipped.normalizer, shipped.num_joints)
    for length in range(10, 10 + CACHED_LENGTHS + 2):
        assert bank.index(length)[0].shape[0] > 0
    assert len(bank._cache) == CACHED_LENGTHS and 10 not in bank._cache and 11 not in bank._cache


def test_infill_says_which_gaps_follow_training_motion(tmp_path, capsys):
    """The CLI on a validation subject's raw 120 Hz walk: the first gap follows a match (infill.json records it),
    the second lies too near the file's end to match, and the CLI says both."""
    import json
    from inbetween_jax.cli import main
    path = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "cmu_bvh", "12_01.bvh")
    if not os.path.exists(path):
        pytest.skip("needs ../shared/data/cmu_bvh")
    out = tmp_path / "o"
    assert main(["infill", "--model", "cae", "--bvh", path, "--gaps", "100:340,380:500", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "gap 1: follows the nearest training motion" in err
    assert "gap 2: not matched to training motion" in err
    rows = json.loads((out / "infill.json").read_text())["gaps_ood"]
    assert rows[0]["match_weight"] == 1.0 and rows[0]["match_departure"] < 0.5
    assert rows[1]["match_weight"] == 0.0 and rows[1]["match_distance"] is None
