"""Users' own BVH folders: frame-rate resampling, the announced split, unit detection, gap merging.

Real CMU files from the shared data folder: 120 Hz salsa takes (``cmu_pairs``, 1/128 of the usual scale),
120 Hz walks (``cmu_bvh``, Daz/Poser skeleton, about cm) and 30 Hz trials of two skeletons (``cmu_more``).
"""
import os
import re

import numpy as np
import pytest

from inbetween_jax.data import read_bvh, windows_from_motions
from inbetween_jax.data.datasets import EMBEDDED_DIR, load_dataset, load_motions, split_files
from inbetween_jax.data.features import KNOWN_UNITS_CM, detect_unit_scale, foot_contacts
from inbetween_jax.data.resample import nominal_fps, resample_motion
from inbetween_jax.data.user_input import merge_gaps, parse_gaps
from inbetween_jax.errors import UserError
from inbetween_jax.geometry.kinematics import forward_kinematics

from conftest import HAS_LAFAN1, LAFAN1_DIR, SHARED_DATA

# From a checkout that is not beside the data, the folder holding LaFAN1_DIR is tried as well.
_CANDIDATES = [SHARED_DATA, os.path.dirname(os.path.abspath(LAFAN1_DIR))]
SHARED = next((d for d in _CANDIDATES if os.path.isdir(os.path.join(d, "cmu_pairs"))), None)
requires_cmu = pytest.mark.skipif(SHARED is None, reason="shared CMU data (cmu_pairs, cmu_bvh, cmu_more) not found")


def shared(*parts):
    return os.path.join(SHARED, *parts)


PAIR = "cmu_pairs/60_10_scaled.bvh"     # 120 Hz, 1/128 scale, the smallest salsa take
WALK = "cmu_bvh/07_05.bvh"              # 120 Hz, Daz/Poser skeleton in about cm
DAZ30 = "cmu_more/daz43/35_24.bvh"      # 30 Hz, the same skeleton
MB30 = "cmu_more/mb31/06_09.bvh"        # 30 Hz, 31-joint skeleton in CMU ASF units


@pytest.fixture(scope="module")
def pair():
    return read_bvh(shared(PAIR))


def folder_of(tmp_path, *files):
    """A folder of links to shared files (tmp_path / "src")."""
    d = tmp_path / "src"
    d.mkdir()
    for f in files:
        os.symlink(shared(f), d / os.path.basename(f))
    return str(d)


def test_nominal_fps_reads_rounded_frame_times():
    assert nominal_fps(0.008333) == 120.0 and nominal_fps(0.033333) == 30.0 and nominal_fps(0.03333332) == 30.0
    assert nominal_fps(0.02) == 50.0 and nominal_fps(1 / 24) == 24.0
    assert abs(nominal_fps(1 / 27.5) - 27.5) < 1e-9


@requires_cmu
def test_integer_ratio_is_an_exact_subsample(pair):
    assert nominal_fps(pair.frame_time) == 120.0
    out = resample_motion(pair, 30)
    assert out.frame_time == pytest.approx(1 / 30) and out.num_frames == (pair.num_frames - 1) // 4 + 1
    np.testing.assert_array_equal(out.local_quats, pair.local_quats[::4])
    np.testing.assert_array_equal(out.local_pos, pair.local_pos[::4])
    assert resample_motion(out, 30) is out   # already at the rate: untouched


@requires_cmu
@pytest.mark.parametrize("fps", [50.0, 24.0, 47.3])
def test_resampling_matches_scipy(pair, fps):
    """Against scipy's Slerp (per joint) and interp1d on the real 120 Hz take, at times k / fps."""
    from scipy.interpolate import interp1d
    from scipy.spatial.transform import Rotation, Slerp
    src = pair.slice(0, 600)
    out = resample_motion(src, fps)
    t_src = np.arange(src.num_frames) / 120.0
    t_out = np.arange(out.num_frames) / fps
    assert t_out[-1] <= t_src[-1] + 1e-9 and t_out[-1] + 1 / fps > t_src[-1]   # covers the whole take
    assert out.frame_time == pytest.approx(1 / fps)
    for j in range(src.skeleton.num_joints):
        ref = Slerp(t_src, Rotation.from_quat(src.local_quats[:, j], scalar_first=True))(t_out)
        got = Rotation.from_quat(out.local_quats[:, j], scalar_first=True)
        assert np.max((ref.inv() * got).magnitude()) < 1e-6, f"joint {j}"
    ref_pos = interp1d(t_src, src.local_pos, axis=0)(t_out)
    np.testing.assert_allclose(out.local_pos, ref_pos, atol=1e-9)
    # unit, sign-continuous quaternions as Motion promises
    np.testing.assert_allclose(np.linalg.norm(out.local_quats, axis=-1), 1.0, atol=1e-12)
    assert np.all(np.sum(out.local_quats[1:] * out.local_quats[:-1], axis=-1) >= 0)


@requires_cmu
def test_120hz_folder_is_resampled_and_announced(tmp_path, monkeypatch, capfd):
    monkeypatch.setenv("INBETWEEN_JAX_CACHE", str(tmp_path / "cache"))
    src = folder_of(tmp_path, WALK, "cmu_bvh/07_04.bvh", "cmu_bvh/08_04.bvh")
    raw = read_bvh(shared(WALK))
    w = load_dataset(src, "train")
    err = capfd.readouterr().err
    assert f"data: {src}: 120 fps files resampled to 30 fps" in err
    assert err.count("resampled to") == 1
    assert w.fps == 30.0 and w.window == 50
    # windows counted at 30 Hz: a window spans 50 / 30 s of the 120 Hz capture
    n30 = (raw.num_frames - 1) // 4 + 1
    walk_windows = [n for n in w.seq_names if n.startswith("07_05@")]
    assert len(walk_windows) == len(range(0, n30 - 50, 20))
    # the cache is keyed by the rate: another rate builds other windows, the same rate reuses them
    w60 = load_dataset(src, "train", fps=60)
    assert "resampled to 60 fps" in capfd.readouterr().err
    assert w60.fps == 60.0 and len(w60) > len(w)
    assert len(os.listdir(tmp_path / "cache" / "windows")) == 2
    again = load_dataset(src, "train")
    assert "120 fps files resampled to 30 fps" in capfd.readouterr().err   # told again from the cache
    np.testing.assert_array_equal(again.local_quats, w.local_quats)


@requires_cmu
def test_mixed_rates_are_each_resampled(tmp_path, capfd):
    src = folder_of(tmp_path, WALK, DAZ30, "cmu_more/daz43/35_26.bvh")   # train: 07_05 (120 Hz), 35_24 (30 Hz)
    motions = load_motions(src, "train")
    err = capfd.readouterr().err
    assert f"data: {src}: 1 file at 120 fps resampled to 30 fps" in err
    assert all(nominal_fps(m.frame_time) == 30.0 for m in motions)
    direct = read_bvh(shared(DAZ30))
    untouched = next(m for m in motions if m.source.endswith("35_24.bvh"))
    np.testing.assert_array_equal(untouched.local_quats, direct.local_quats)


@requires_cmu
def test_split_is_announced_once(tmp_path, monkeypatch, capfd):
    monkeypatch.setenv("INBETWEEN_JAX_CACHE", str(tmp_path / "cache"))
    names = ["cmu_more/daz43/35_24.bvh", "cmu_more/daz43/35_26.bvh", "cmu_more/daz43/16_39.bvh",
             "cmu_more/daz43/35_23.bvh", "cmu_more/daz43/35_25.bvh"]
    src = folder_of(tmp_path, *names)
    test = split_files(src, "test")
    assert [os.path.basename(f) for f in test] == ["35_26.bvh"]       # the last 20 % by name
    load_dataset(src, "train", window=20, offset=10)
    lines = [ln for ln in capfd.readouterr().err.splitlines() if "test files" in ln]
    assert lines == [f"data: {src}: 4 train / 1 test files (the last 20 % by name); test: 35_26.bvh"]
    load_dataset(src, "test", window=20, offset=10)                    # the test split says nothing more
    assert "test files" not in capfd.readouterr().err
    # two files: one of each, never an empty test split
    two = tmp_path / "two"
    two.mkdir()
    for n in names[:2]:
        os.symlink(shared(n), two / os.path.basename(n))
    assert len(split_files(str(two), "train")) == len(split_files(str(two), "test")) == 1
    # one file: used for both, and said so
    one = tmp_path / "one"
    one.mkdir()
    os.symlink(shared(DAZ30), one / "35_24.bvh")
    assert split_files(str(one), "train") == split_files(str(one), "test") == [str(one / "35_24.bvh")]
    load_motions(str(one), "train")
    assert f"data: {one}: 1 file (35_24.bvh), used for both training and test" in capfd.readouterr().err


@requires_cmu
def test_different_skeletons_and_units_are_one_line_errors(tmp_path):
    # train: 06_08, 06_09 (31 joints) and 35_24 (43 joints); test: 35_26
    src = folder_of(tmp_path, DAZ30, MB30, "cmu_more/mb31/06_08.bvh", "cmu_more/daz43/35_26.bvh")
    with pytest.raises(ValueError) as e:
        load_motions(src, "train")
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(os.path.join(src, "35_24.bvh"))
    assert "43 joints instead of 31" in msg
    # the same skeleton in two units: the 1/128 salsa take beside a cm-scale walk
    both = tmp_path / "units"
    both.mkdir()
    for name, f in (("a.bvh", PAIR), ("b.bvh", DAZ30), ("c.bvh", "cmu_more/daz43/35_26.bvh")):
        os.symlink(shared(f), both / name)                            # train: a, b; test: c
    with pytest.raises(ValueError, match=r"b\.bvh: its bone lengths put it at 1 cm per unit but .*a\.bvh at 130"):
        load_motions(str(both), "train")
    assert len(load_motions(str(both), "train", unit_scale=1.0)) == 2  # an explicit unit is the user's word


@requires_cmu
def test_unit_scale_detection_on_real_skeletons():
    embedded = read_bvh(os.path.join(EMBEDDED_DIR, "02_01.bvh")).skeleton
    daz = read_bvh(shared(DAZ30), end=2).skeleton
    pair = read_bvh(shared(PAIR), end=2).skeleton
    mb = read_bvh(shared(MB30), end=2).skeleton
    assert detect_unit_scale(embedded) == 1.0 and detect_unit_scale(daz) == 1.0
    assert detect_unit_scale(mb) == KNOWN_UNITS_CM[-1] == pytest.approx(5.6444, abs=1e-4)  # 1/0.45 inch
    # the salsa files are the same body with every offset divided by 128 (the data README)
    np.testing.assert_allclose(pair.offsets[1:] * 128, daz.offsets[1:], rtol=1e-3, atol=1e-3)
    assert detect_unit_scale(pair) == pytest.approx(128, rel=0.05)
    if HAS_LAFAN1:
        lafan = read_bvh(os.path.join(LAFAN1_DIR, sorted(f for f in os.listdir(LAFAN1_DIR)
                                                          if f.endswith(".bvh"))[0]), end=2).skeleton
        assert detect_unit_scale(lafan) == 1.0


@requires_cmu
def test_contacts_use_centimetres(pair):
    """Contact thresholds are in cm: on the 1/128-scale take, the detected scale labels feet like the
    same motion in cm would be labelled, where raw units call almost every frame a contact."""
    m = resample_motion(pair, 30)
    scale = detect_unit_scale(m.skeleton)
    feet = list(m.skeleton.foot_joints())
    _, gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)
    in_cm = foot_contacts(gp[:, feet] * scale, 1.0)
    np.testing.assert_array_equal(foot_contacts(gp[:, feet], 1.0, scale), in_cm)
    assert 0.2 < in_cm.mean() < 0.85                       # dancing feet: planted part of the time
    assert foot_contacts(gp[:, feet], 1.0).mean() > 0.99    # the bug: 1/128 units look motionless
    w = windows_from_motions([m], 50, 20, 10, tuple(m.skeleton.forward_axis()), 1.0, scale)
    assert w.unit_scale == scale and 0.2 < w.contacts.mean() < 0.85


def test_embedded_scale_is_exactly_one(tmp_path, monkeypatch):
    monkeypatch.setenv("INBETWEEN_JAX_CACHE", str(tmp_path))
    w = load_dataset("embedded", "test")
    assert w.unit_scale == 1.0 and w.fps == pytest.approx(30.0, abs=1e-3)
    forced = load_dataset("embedded", "test", unit_scale=1.0)        # explicit 1.0: the same windows
    np.testing.assert_array_equal(forced.contacts, w.contacts)
    assert len(os.listdir(tmp_path / "windows")) == 2               # but its own cache entry
    with pytest.raises(ValueError, match="unit_scale must be a positive"):
        load_dataset("embedded", "test", unit_scale=-1)


def test_gaps_overlapping_or_touching_are_merged():
    notes = []
    assert parse_gaps("20:40,30:50", notes=notes) == [(20, 50)]
    assert notes == ["--gaps 20:40,30:50: overlapping gaps merged into 20:50"]
    notes = []
    assert parse_gaps("300:420, 100:160,160:200", 500, "a.bvh", notes) == [(100, 200), (300, 420)]
    assert notes == ["--gaps 300:420, 100:160,160:200: touching gaps merged into 100:200"]
    assert merge_gaps([(5, 9), (0, 3)]) == ([(0, 3), (5, 9)], None)
    assert merge_gaps([(0, 10), (2, 3), (10, 12)]) == ([(0, 12)], "overlapping or touching gaps merged into 0:12")
    assert parse_gaps("1:5,2:3") == [(1, 5)]                        # notes are optional
    with pytest.raises(UserError, match="cover all 100 frames"):
        parse_gaps("0:60,50:100", 100, "a.bvh")


# ---- the cmu source and the validation split -------------------------------------------------------------------

def _trials(files):
    from inbetween_jax.data.sources import trial_name
    return [trial_name(f) for f in files]


@pytest.fixture
def cmu_env(monkeypatch):
    monkeypatch.setenv("INBETWEEN_SHARED_DATA", SHARED)


@requires_cmu
def test_cmu_splits(cmu_env):
    train, val, fit = (split_files("cmu", s) for s in ("train", "val", "fit"))
    test = split_files("cmu", "test")
    assert test == split_files("embedded", "test") and split_files("cmu", "benchmark") == test
    assert all(os.path.basename(f).startswith(("13_", "14_")) for f in test)
    names = _trials(train)
    assert not [n for n in names if n.startswith(("13_", "14_"))] and not set(test) & set(train)
    assert len(set(names)) == len(names)                       # no trial twice (embedded copies dropped)
    assert set(split_files("embedded", "train")) <= set(train)
    folders = {os.path.basename(os.path.dirname(f)) for f in train}
    assert folders == {"cmu30", "cmu_bvh", "daz43", "mb31", "cmu_pairs"}
    assert sorted(_trials(f for f in train if "cmu_bvh" in f)) == ["16_01", "16_02", "18_01"]  # the 31-joint ones
    assert sum(os.path.basename(os.path.dirname(f)) == "mb31" for f in train) == 51
    assert sum("_scaled" in f for f in train) == 24
    assert not set(val) & set(fit) and sorted(val + fit) == sorted(train)
    assert 0.08 * len(train) <= len(val) <= 0.15 * len(train)
    takes = {os.path.basename(f)[3:] for f in val if "_scaled" in f}
    for t in takes:                                             # both dancers of a take on one side
        assert any(f.endswith("60_" + t) for f in val) and any(f.endswith("61_" + t) for f in val)


@requires_cmu
def test_val_split_of_every_source_kind(tmp_path, cmu_env):
    from inbetween_jax.data.sources import val_files
    emb = split_files("embedded", "train")
    val = split_files("embedded", "val")
    assert 1 <= len(val) <= 0.15 * len(emb) + 1 and set(val) <= set(emb)
    assert set(val_files(emb[::-1])) == set(val)               # by name, not by listing order
    assert split_files("embedded", "train") == emb              # train unchanged
    folder = folder_of(tmp_path, "cmu_more/daz43/35_01.bvh", "cmu_more/daz43/35_02.bvh",
                       "cmu_more/daz43/35_03.bvh", "cmu_more/daz43/35_04.bvh", "cmu_more/daz43/35_05.bvh")
    g_train, g_val, g_fit = (split_files(folder, s) for s in ("train", "val", "fit"))
    assert len(g_train) == 4 and len(g_val) == 1 and sorted(g_val + g_fit) == g_train
    one = tmp_path / "one"
    one.mkdir()
    os.symlink(shared(DAZ30), one / "a.bvh")
    with pytest.raises(ValueError, match="at least two trials"):
        split_files(str(one), "val")
    if HAS_LAFAN1:
        l_val, l_train = split_files(LAFAN1_DIR, "val"), split_files(LAFAN1_DIR, "train")
        assert l_val and set(l_val) <= set(l_train) and not any("subject5" in f for f in l_val)


def test_subject_validation_groups_whole_performers():
    """``by="subject"`` keeps every file of a performer on one side: CMU subjects by trial name, the salsa
    pair's takes as one group (both dancers are in every take), LaFAN1 ``subjectN``; an unknown grouping and a
    single subject are one-line errors."""
    from inbetween_jax.data.sources import _val_group, val_files
    names = ["a/05_01.bvh", "a/05_02.bvh", "b/07_01.bvh", "b/07_12.bvh", "c/60_01_scaled.bvh", "c/61_01_scaled.bvh",
             "c/60_02_scaled.bvh", "d/walk1_subject1.bvh", "d/run2_subject1.bvh", "d/walk1_subject3.bvh",
             "e/take.bvh"]
    assert [_val_group(f, "subject") for f in names] == [
        "subject 05", "subject 05", "subject 07", "subject 07", "salsa", "salsa", "salsa", "subject1", "subject1",
        "subject3", "take"]
    assert _val_group("c/60_02_scaled.bvh") == "salsa_02" and _val_group("a/05_02.bvh") == "05_02"   # by file
    for fraction in (0.1, 0.3, 0.5):
        val = val_files(names, fraction, by="subject")
        groups = {_val_group(f, "subject") for f in val}
        assert val and all(_val_group(f, "subject") in groups for f in names if f in val)
        assert not any(_val_group(f, "subject") in groups for f in names if f not in val)   # whole subjects
        assert val == [f for f in names if f in val] and set(val_files(names[::-1], fraction, by="subject")) == set(val)
    with pytest.raises(ValueError, match="unknown validation grouping 'take'"):
        val_files(names, by="take")
    with pytest.raises(ValueError, match="at least two subjects"):
        val_files(["a/05_01.bvh", "a/05_02.bvh"], by="subject")


@requires_cmu
def test_cmu_subject_split_holds_whole_subjects_out(cmu_env):
    from inbetween_jax.data.datasets import val_note
    from inbetween_jax.data.sources import _val_group
    train, val, fit = (split_files("cmu", s) for s in ("train", "val-subjects", "fit-subjects"))
    assert sorted(val + fit) == sorted(train) and not set(val) & set(fit)
    held = {_val_group(f, "subject") for f in val}
    assert held and not held & {_val_group(f, "subject") for f in fit}
    assert len(val) >= 0.1 * len(train)
    assert split_files("cmu", "val") != val                    # not the by-file split
    note = val_note("cmu", "fit-subjects")
    assert f"validation split {len(val)} of {len(train)}" in note and "whole subjects" in note


@requires_cmu
def test_activity_split_leaves_whole_activity_subjects_out(cmu_env):
    """``fit-activities`` is ``fit-subjects`` without the subjects of sports, Indian dance and karate;
    ``val-activities`` is every training file of those subjects; the validation subjects are untouched."""
    from inbetween_jax.data.datasets import LEFT_OUT_ACTIVITY_SUBJECTS, is_fit_split, val_split_of
    from inbetween_jax.data.sources import subject_of
    fit, left, sfit = (split_files("cmu", s) for s in ("fit-activities", "val-activities", "fit-subjects"))
    assert {subject_of(f) for f in left} == set(LEFT_OUT_ACTIVITY_SUBJECTS)
    assert not set(fit) & set(left) and set(fit) <= set(sfit)
    assert sorted(fit + [f for f in left if f in sfit]) == sorted(sfit)
    assert not {subject_of(f) for f in fit} & set(LEFT_OUT_ACTIVITY_SUBJECTS)
    assert not set(left) & set(split_files("cmu", "val-subjects"))
    assert any("135_" in f for f in left) and any("94_" in f for f in left)
    assert is_fit_split("fit-activities") and val_split_of("fit-activities") == "val-subjects"
    with pytest.raises(ValueError, match="cmu source only"):
        split_files("embedded", "val-activities")
    from types import SimpleNamespace
    from inbetween_jax.banks import run_fit_split               # a run's bank leaves the same subjects out
    for own in ("fit-activities", "fit-subjects"):
        assert run_fit_split(SimpleNamespace(config={"train": {"split": own}}), "fit") == own
    from inbetween_jax.data.datasets import window_settings      # windows as the training files' (was refused)
    assert window_settings("cmu", "val-activities") == window_settings("cmu", "fit-activities")
    assert run_fit_split(SimpleNamespace(config={"train": {"split": "fit"}}), "fit") == "fit"


@requires_cmu
def test_missing_shared_folder_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setenv("INBETWEEN_SHARED_DATA", str(tmp_path / "nowhere"))
    with pytest.raises(UserError, match="set INBETWEEN_SHARED_DATA") as err:
        split_files("cmu", "train")
    assert "\n" not in str(err.value)
    assert split_files("cmu", "test") == split_files("embedded", "test")   # the test split needs no shared data


@requires_cmu
def test_cmu_motions_share_the_embedded_skeleton_and_unit():
    from inbetween_jax.data.sources import reference_skeleton, to_reference
    ref = reference_skeleton()
    files = [os.path.join(EMBEDDED_DIR, "02_01.bvh"), shared("cmu_more/daz43/35_01.bvh"), shared(PAIR),
             shared(WALK), shared("cmu_more/daz43/16_12.bvh")]
    out = {}
    for f in files:
        raw = read_bvh(f)
        m, factor = to_reference(raw, ref, 30.0)
        assert m.skeleton is ref and m.local_quats.shape[1:] == (21, 4) and m.fps == pytest.approx(30.0, rel=1e-4)
        np.testing.assert_allclose(m.local_pos[:, 1:], np.broadcast_to(ref.offsets[1:], m.local_pos[:, 1:].shape))
        out[os.path.basename(f)] = (m, factor, raw)
    assert out["60_10_scaled.bvh"][1] == pytest.approx(128.0, rel=1e-4)          # the 1/128 salsa files
    assert all(out[k][1] == 1.0 for k in out if k != "60_10_scaled.bvh")
    hips = {k: m.local_pos[0, 0, 1] for k, (m, _, _) in out.items()}
    assert max(hips.values()) / min(hips.values()) < 1.2, hips                      # one unit everywhere
    assert abs(hips["60_10_scaled.bvh"] / hips["07_05.bvh"] - 1) < 0.25
    # a leading T-pose frame is dropped (35_01 starts with one, 16_12 does not; the salsa takes neither)
    assert out["35_01.bvh"][0].num_frames == out["35_01.bvh"][2].num_frames - 1
    assert out["16_12.bvh"][0].num_frames == out["16_12.bvh"][2].num_frames
    assert out["60_10_scaled.bvh"][0].num_frames == (out["60_10_scaled.bvh"][2].num_frames - 1) // 4 + 1
    raw = out["35_01.bvh"][2]
    idx = [raw.skeleton.names.index(n) for n in ref.names]                      # the body joints, in order
    np.testing.assert_allclose(out["35_01.bvh"][0].local_quats, raw.local_quats[1:, idx])


@requires_cmu
def test_cmu_reads_the_31_joint_rig_on_the_embedded_body(cmu_env):
    """An mb31 capture in the cmu training set: put on the embedded 21-joint body in its unit, at 30 Hz, its
    T-pose frame dropped, feet near the floor and hips at a standing height like the daz43 files'."""
    from inbetween_jax.data.sources import read_cmu_train, reference_skeleton
    (m, daz), note = read_cmu_train([shared(MB30), shared(DAZ30)], "val", 30.0)
    assert "cmu_more/mb31 1 files" in note and "retargeted by bone directions" in note
    assert m.skeleton is reference_skeleton() and m.num_frames == read_bvh(shared(MB30)).num_frames - 1
    g, gd = m.global_positions(), daz.global_positions()
    feet = [m.skeleton.names.index(n) for n in ("lFoot", "rFoot")]
    assert 0.0 < g[:, feet, 1].min() < 15.0 and abs(np.median(g[:, 0, 1]) / np.median(gd[:, 0, 1]) - 1) < 0.2


@requires_cmu
@pytest.mark.slow
def test_cmu_windows_and_cache(cmu_env, tmp_path, monkeypatch, capfd):
    """The whole cmu training set (~150 files, about a minute cold): one skeleton and unit, more windows than
    the embedded set, fit + val = train window for window, and the cache gives the same arrays."""
    monkeypatch.setenv("INBETWEEN_JAX_CACHE", str(tmp_path / "cache"))
    from inbetween_jax.data.sources import reference_skeleton
    train = load_dataset("cmu", "train")
    err = capfd.readouterr().err
    assert "data: cmu: training on 200 files" in err and "0 files on another skeleton (none)" in err
    assert "cmu_more/mb31 51 files" in err and "retargeted by bone directions" in err
    assert re.search(r"cmu_bvh 3 files [0-9.]+ min, retargeted by bone directions", err)   # 16_01, 16_02, 18_01
    assert train.skeleton.names == reference_skeleton().names and train.unit_scale == 1.0
    assert len(train) > 3 * len(load_dataset("embedded", "train"))
    val, fit = load_dataset("cmu", "val"), load_dataset("cmu", "fit")
    assert len(val) + len(fit) == len(train) and not set(val.seq_names) & set(fit.seq_names)
    again = load_dataset("cmu", "train")
    assert "training on 200 files" in capfd.readouterr().err
    np.testing.assert_array_equal(again.local_quats, train.local_quats)
    assert len(load_dataset("cmu", "test")) == len(load_dataset("embedded", "test"))
