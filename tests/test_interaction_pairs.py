"""Real two-person capture (CMU subjects 60 + 61 salsa in ``../shared/data/cmu_pairs``): pair discovery, the
fixed split per take, units, per-joint Euler orders (checked against the independent ``bvhio`` reader), dropped
joints, and the real-pair baselines of the interaction protocol."""
from __future__ import annotations

import os

import jax
import numpy as np
import pytest

from inbetween_jax.data import read_bvh
from inbetween_jax.data.bvh import motion_to_channels
from inbetween_jax.evaluation import interaction as proto
from inbetween_jax.geometry.kinematics import forward_kinematics
from inbetween_jax.geometry.quaternion import quat_from_euler
from inbetween_jax.models.interaction import data as idata
from inbetween_jax.models.interaction import batches as ibatches

PAIRS_DIR = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "cmu_pairs")
needs_pairs = pytest.mark.skipif(not os.path.isdir(PAIRS_DIR), reason="../shared/data/cmu_pairs not available")


@pytest.fixture(scope="module")
def take12():
    """Take 12 (a test take) as one real pair: 30 Hz, centimetres, all 43 joints."""
    return idata.load_pair(os.path.join(PAIRS_DIR, "60_12_scaled.bvh"), os.path.join(PAIRS_DIR, "61_12_scaled.bvh"),
                           "60+61_12")


@needs_pairs
def test_one_take_units_and_rate(take12):
    assert take12.fps == 30.0 and take12.num_frames == 423          # 1690 frames at 120 fps -> 423 at 30 Hz
    hips = take12.feats[:, :, 0, 1] / 100.0                          # cm -> m
    assert 0.8 <= np.median(hips) <= 1.1
    # the partners dance close together (median root distance on the floor under 1.2 m)
    sep = np.linalg.norm((take12.feats[0, :, 0, :3] - take12.feats[1, :, 0, :3])[:, [0, 2]], axis=-1) / 100.0
    assert 0.3 < np.median(sep) < 1.2


@needs_pairs
def test_pairs_found_by_take_id_and_split_per_take():
    found = idata.find_pair_files(PAIRS_DIR)
    assert len(found) == 12
    for name, a, b in found:
        take = name.split("_")[-1]
        assert os.path.basename(a) == f"60_{take}_scaled.bvh" and os.path.basename(b) == f"61_{take}_scaled.bvh"
    splits = dict(zip([n for n, _, _ in found], idata.real_pair_splits(PAIRS_DIR, [n for n, _, _ in found])))
    assert sorted(n for n, s in splits.items() if s == "test") == ["60+61_12", "60+61_13"]
    assert sum(s == "train" for s in splits.values()) == 10


@pytest.mark.slow
@needs_pairs
def test_all_real_pairs_split_per_take():
    real_pairs = idata.load_pairs(PAIRS_DIR)
    assert all(not p.constructed and p.fps == 30.0 and p.feats.shape[2] == 21 for p in real_pairs)
    test = idata.split_pairs(real_pairs, "test")
    assert [p.name for p in test] == ["60+61_12", "60+61_13"]
    assert not {p.name for p in test} & {p.name for p in idata.split_pairs(real_pairs, "train")}


def test_validation_split_holds_out_the_last_training_take():
    """Whole takes: ``val`` is the last training take by name, ``fit`` the other training takes; the test takes
    stay out of both (checkpoint selection never sees them)."""
    from types import SimpleNamespace
    takes = [SimpleNamespace(name=f"60+61_{n:02d}", split="test" if n >= 12 else "train", constructed=False)
             for n in (1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13)]
    names = {s: [p.name for p in idata.split_pairs(takes, s)] for s in ("train", "fit", "val", "test")}
    assert names["val"] == ["60+61_11"] and names["test"] == ["60+61_12", "60+61_13"]
    assert names["fit"] == names["train"][:-1] and "60+61_11" in names["train"]
    with pytest.raises(ValueError, match="unknown pair split"):
        idata.split_pairs(takes, "dev")


def test_constructed_validation_pair_shares_no_clip_with_fit():
    """Embedded constructed pairs chain neighbouring clips (a+b, b+c): the held-out pair's clips appear in no
    ``fit`` pair, and it is not a test pair."""
    pairs = idata.load_pairs("embedded")
    fit, val, test = (idata.split_pairs(pairs, s) for s in ("fit", "val", "test"))
    assert len(val) == 1 and val[0].name not in {p.name for p in test}
    clips = set(val[0].name.split("+"))
    assert not any(clips & set(p.name.split("+")) for p in fit)
    assert len(fit) >= len(idata.split_pairs(pairs, "train")) - 2


@needs_pairs
def test_fk_matches_bvhio_with_mixed_euler_orders():
    bvhio = pytest.importorskip("bvhio")
    path = os.path.join(PAIRS_DIR, "60_12_scaled.bvh")
    m = read_bvh(path, 700, 701)
    assert m.skeleton.rotation_order(0) == "zyx" and m.skeleton.rotation_order(1) == "zxy"
    root = bvhio.readAsHierarchy(path)
    root.loadPose(700)
    joints = [j for j, _, _ in root.layout()]
    assert [j.Name for j in joints] == list(m.skeleton.names)
    theirs = np.array([list(j.PositionWorld) for j in joints])
    ours = m.global_positions()[0]
    np.testing.assert_allclose(ours, theirs, atol=1e-5)
    # reading every joint with the root's Euler order (z y x) would not agree: the per-joint order matters
    vals, col, quats = motion_to_channels(m), 0, []
    for ch in m.skeleton.channels:
        rot = {c[0]: vals[:, col + k] for k, c in enumerate(ch) if c.endswith("rotation")}
        quats.append(quat_from_euler(np.radians(np.stack([rot["Z"], rot["Y"], rot["X"]], -1)), "zyx"))
        col += len(ch)
    bad = forward_kinematics(np.stack(quats, 1), m.local_pos, m.skeleton.parents)[1][0]
    assert np.abs(bad - theirs).max() > 0.01


@needs_pairs
def test_dropped_joints_never_move():
    motions = [m for _, a, b in idata.find_pair_files(PAIRS_DIR)[:3] for m in (read_bvh(a), read_bvh(b))]
    still = idata.static_joints(motions)
    names = np.array(motions[0].skeleton.names)
    assert "leftEye" in names[still] and "rIndex1" in names[still]
    assert not {"hip", "rHand", "lFoot", "rCollar"} & set(names[still])   # collars keep moving children
    for m in motions:
        q = m.local_quats[:, still]
        assert np.abs(np.abs(np.sum(q * q[:1], -1)) - 1.0).max() < 1e-9
    skel = idata.subset_skeleton(motions[0].skeleton, ~still)
    assert skel.num_joints == 21 and skel.foot_joints()[0] == skel.index("lFoot")


@needs_pairs
def test_real_pair_baselines_on_test_windows(take12):
    w = ibatches.eval_windows([take12], proto.N_INPUT, 30, 60, 0.01, max_windows=2)
    key = jax.random.key(0)
    interp = proto.interpolation_method(w, 6, 1, key)
    hold = proto.hold_method(w, 6, 1, key)
    guess = proto.guessed_interpolation_method(w, 6, 1, key)
    gt = w["x"][:, :, proto.N_INPUT:proto.N_INPUT + 30]
    assert interp.shape == hold.shape == guess.shape == (1, 2, 2, 60) + w["x"].shape[3:]
    err = {k: np.abs(v[0, :, :, :30, :, :3] - gt[..., :3]).mean() for k, v in
           dict(interp=interp, hold=hold).items()}
    assert err["interp"] < err["hold"]                      # interpolation toward the keypose beats freezing
    g = proto.guess_gap_length(w)
    assert g.shape == (2,) and (g >= 5).all() and (g <= 200).all()
    # stop rule: interpolation with the true length arrives by frame 30 + 1; holding rarely arrives
    true_len = proto.arrival_stats(lambda b, s, n, k: proto._interp_then_hold(b, np.full(2, 30), s * 10)[None], w)
    assert true_len["reached"] == 1.0 and true_len["median_frames"] <= 31
    held = proto.arrival_stats(proto.hold_method, w)
    assert held["reached"] < 1.0
    # the per-character hook applied to a per-character method changes nothing
    indep = proto.independent_method(proto.interpolation_method)(w, 3, 1, key)
    np.testing.assert_allclose(indep, proto.interpolation_method(w, 3, 1, key), atol=1e-5)


@needs_pairs
def test_windows_l2p_scores_ground_truth_zero_and_interpolation_as_pair_l2p(take12):
    """The selection / all-windows score: ground truth scores 0; interpolation the direct pair L2P of its frames."""
    from inbetween_jax.baselines.two_character import two_character_interpolation
    from inbetween_jax.models.interaction.bench import windows_l2p
    windows = {L: ibatches.eval_windows([take12], proto.N_INPUT, L, 60, 0.01, max_windows=3) for L in (30, 50)}
    stats = proto.l2p_stats([take12], 0.01)
    assert windows_l2p(proto.ground_truth_method, windows, stats) == pytest.approx([0.0, 0.0], abs=1e-6)
    got = windows_l2p(proto.interpolation_method, windows, stats)
    want = [proto.pair_l2p(np.asarray(two_character_interpolation(w["x"][:, :, proto.N_INPUT - 1], w["keypose"], L)),
                           w, stats) for L, w in windows.items()]
    assert got == pytest.approx(want, rel=1e-6) and all(v > 0.1 for v in got)


@needs_pairs
def test_tempo_and_reversed_copies_only_of_training_takes(tmp_path):
    """``data.tempo`` adds each training take resampled from the files (speed 1.25: 120 Hz -> 24 Hz played at
    30 Hz, so copy frame 4 is source time 1/6 s = original frame 5); ``data.reverse`` adds every pair played
    backwards; validation and test pairs are never augmented."""
    import dataclasses

    from inbetween_jax.models.interaction.config import get_config
    from inbetween_jax.models.interaction.train import load_data
    for take in ("12", "13"):
        for subject in ("60", "61"):
            os.symlink(os.path.abspath(os.path.join(PAIRS_DIR, f"{subject}_{take}_scaled.bvh")),
                       tmp_path / f"{subject}_{take}_scaled.bvh")
    (tmp_path / "pairs.txt").write_text("60_12_scaled.bvh 61_12_scaled.bvh train\n"
                                        "60_13_scaled.bvh 61_13_scaled.bvh test\n")
    cfg = get_config("tiny")
    cfg = dataclasses.replace(cfg, data=dataclasses.replace(cfg.data, tempo=(1.25,), reverse=True))
    train = load_data(cfg, str(tmp_path), "train").pairs
    assert [p.name for p in train] == ["60_12_scaled", "60_12_scaled@1.25x", "60_12_scaled@rev",
                                       "60_12_scaled@1.25x@rev"]
    orig, fast, rev = train[0], train[1], train[2]
    assert orig.num_frames == 423 and fast.num_frames == 338 and fast.fps == 30.0   # floor(1689 * 24 / 120) + 1
    np.testing.assert_array_equal(fast.feats[:, 4::4], orig.feats[:, 5::5][:, :fast.feats[:, 4::4].shape[1]])
    assert not np.allclose(fast.feats[:, 1], orig.feats[:, 1])
    np.testing.assert_array_equal(rev.feats, orig.feats[:, ::-1])
    assert [p.name for p in load_data(cfg, str(tmp_path), "test").pairs] == ["60_13_scaled"]
    constructed = [dataclasses.replace(orig, constructed=True)]
    with pytest.raises(ValueError, match="data.tempo needs whole real takes"):
        idata.augmented_pairs(constructed, str(tmp_path), (1.25,))
