"""``inbetween infill`` never reads the frames it replaces: on a validation subject's walk whose gap frames (CAE) or
frames between the keyframes (S-CVAE; a salsa pair's for the interaction model) are swapped for other motion, the
features of every known frame, the gate's and the match's scores and the whole output are the same as with the
captured frames; the first velocity after a gap is the next step's; the frame-rate conversion of gaps and keyframes
leaves no known frame interpolated from a frame of the fill; a keyframe's foot contacts come from its side of the
fill."""
from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from conftest import SHARED_DATA
from inbetween_jax.cli import main
from inbetween_jax.data import load_motions, read_bvh
from inbetween_jax.data.bvh import write_bvh
from inbetween_jax.data.resample import sample_times
from inbetween_jax.data.user_input import resampled_gaps
from inbetween_jax.models.cae.features import body_frame_features, integrate_root, split_features

GAP = (40, 70)


@pytest.fixture(scope="module")
def walks():
    """A validation subject's 30 fps walk, and the same file with its gap frames replaced by the walk played
    backwards (another place, the other way)."""
    walk = [m for m in load_motions("cmu", "val-subjects") if os.path.basename(str(m.source)) == "12_02.bvh"][0]
    a, b = GAP
    lq, lp = np.array(walk.local_quats), np.array(walk.local_pos)
    lq[a:b], lp[a:b] = lq[::-1][a:b], lp[::-1][a:b]
    return walk, dataclasses.replace(walk, local_quats=lq, local_pos=lp)


def test_known_frames_features_do_not_read_the_gap(walks):
    walk, other = walks
    a, b = GAP
    known = np.ones(walk.num_frames, bool)
    known[a:b] = False
    f, g = (body_frame_features(m, known=known) for m in walks)
    np.testing.assert_array_equal(f.features[known], g.features[known])
    np.testing.assert_array_equal(f.ref[known], g.ref[known])
    np.testing.assert_array_equal(f.yaw[known], g.yaw[known])
    leaky = [body_frame_features(m) for m in walks]           # the whole file's features do read it
    assert np.abs(leaky[0].features[b] - leaky[1].features[b]).max() > 1.0
    np.testing.assert_array_equal(f.features[b, -3:], f.features[b + 1, -3:])    # the next step's velocity
    whole = body_frame_features(walk)
    np.testing.assert_allclose(whole.ref, f.ref)
    ref, yaw = integrate_root(split_features(whole.features, walk.skeleton.num_joints)[1], whole.ref0, whole.yaw0)
    np.testing.assert_allclose(ref, whole.ref, atol=1e-6)    # the track is the one the velocities integrate to
    np.testing.assert_allclose(yaw, whole.yaw, atol=1e-9)


def test_cae_infill_is_the_same_whatever_the_gap_holds(walks):
    """Inside the file, and gaps at its first and last frames (there the root hangs from the known side)."""
    from inbetween_jax.models.cae.infer import load, process_motion
    from inbetween_jax.shipped import shipped_run
    model = load(shipped_run("cae"))
    walk = walks[0]
    t = walk.num_frames
    for gap in (GAP, (0, 30), (t - 30, t)):
        lq, lp = np.array(walk.local_quats), np.array(walk.local_pos)
        lq[gap[0]:gap[1]], lp[gap[0]:gap[1]] = lq[::-1][gap[0]:gap[1]], lp[::-1][gap[0]:gap[1]]
        other = dataclasses.replace(walk, local_quats=lq, local_pos=lp)
        res = [process_motion(model, m, [gap]) for m in (walk, other)]
        np.testing.assert_array_equal(res[0]["positions"], res[1]["positions"])
        np.testing.assert_array_equal(res[0]["motion"].local_quats, res[1]["motion"].local_quats)
        assert res[0]["gaps_ood"] == res[1]["gaps_ood"]
        if gap == GAP:
            assert res[0]["gaps_ood"][0]["match_weight"] > 0.5


@pytest.mark.parametrize("src_fps", [120.0, 25.0, 50.0])
def test_resampled_gaps_leave_no_known_frame_reading_a_gap(src_fps):
    """Every resampled frame outside the converted gaps is interpolated from frames outside the file's gaps, and
    every frame inside them reads a gap frame (the conversion is tight), for gaps at many offsets."""
    n_src = 400
    u = sample_times(n_src, src_fps, 30.0)
    n_out = len(u)
    i0 = np.floor(u + 1e-9).astype(int)
    w = u - i0
    for a in range(3, 60):
        for length in (1, 2, 5, 17):
            gaps = [(a, a + length), (a + 150, a + 150 + 3 * length)]
            out = resampled_gaps(gaps, 30.0 / src_fps, n_out, "", "f.bvh")
            bad = np.zeros(n_src + 1, bool)
            for lo, hi in gaps:
                bad[lo:hi] = True
            def reading(lo, hi):
                bad = np.zeros(n_src + 1, bool)
                bad[lo:hi] = True
                return bad[i0] | ((np.abs(w) > 1e-9) & bad[np.minimum(i0 + 1, n_src)])
            per_gap = [reading(lo, hi) for lo, hi in gaps]
            reads = np.any(per_gap, axis=0)
            filled = np.zeros(n_out, bool)
            for lo, hi in out:
                filled[lo:hi] = True
            assert not (reads & ~filled).any(), (src_fps, gaps, out)
            # tight: a filled frame that reads no gap frame only stands for a gap no frame reads
            assert (filled & ~reads).sum() <= sum(not r.any() for r in per_gap), (src_fps, gaps, out)


@pytest.mark.parametrize("src_fps", [120.0, 25.0, 50.0, 30.0])
def test_keyframes_at_another_rate_read_no_frame_of_the_fill(src_fps):
    """The S-CVAE's and the interaction model's keyframes at the model's rate: a start keyframe is interpolated
    from file frames at or before its own, an end keyframe from frames at or after it, at most one converted frame
    away."""
    from types import SimpleNamespace
    from inbetween_jax.data.retarget import Prepared, to_frame
    n_src = 300
    u = sample_times(n_src, src_fps, 30.0)
    prep = Prepared("f.bvh", SimpleNamespace(num_frames=len(u)), None, None, 30.0 / src_fps, None)
    for f in range(1, 250):
        s, e = to_frame(prep, f, "start"), to_frame(prep, f, "end")
        reads_s = np.ceil(u[s] - 1e-9)                  # the latest file frame the converted frame is built from
        reads_e = np.floor(u[e] + 1e-9)                 # the earliest
        assert reads_s <= f and reads_e >= f, (f, s, e)
        assert f - u[s] < src_fps / 30.0 + 1e-9 and u[e] - f < src_fps / 30.0 + 1e-9
        assert abs(to_frame(prep, f) - f * 30.0 / src_fps) <= 0.5 + 1e-9    # no side: the nearest


def test_a_rate_stored_a_little_off_moves_no_gap_end():
    """A checkpoint rate stored as 30.000012 fps (ratio 0.2500001 to a 120 Hz file) converts gaps as 30 fps does."""
    gaps = [(40, 120), (200, 240), (301, 322)]
    want = resampled_gaps(gaps, 0.25, 86, "", "f.bvh")
    assert want == [(10, 30), (50, 60), (76, 81)]
    assert resampled_gaps(gaps, 30.000012 / 120.0, 86, "", "f.bvh") == want
    assert resampled_gaps(gaps, 29.999988 / 120.0, 86, "", "f.bvh") == want


def test_cli_output_is_the_same_whatever_the_gap_holds(tmp_path, capsys):
    """The whole user path (a raw 120 Hz, 43-joint validation walk; resampled to 30 fps, joints matched, filled,
    expanded, written): a file whose gap frames hold the walk played backwards gives the same BVH and infill.json
    scores as the captured file."""
    _swapped(tmp_path, 201, 322)
    outs = []
    for name in ("captured", "broken"):
        assert main(["infill", "--model", "cae", "--bvh", str(tmp_path / f"{name}.bvh"), "--gaps", "201:322",
                     "--out", str(tmp_path / name)]) == 0, capsys.readouterr().err
        info = json.load(open(tmp_path / name / "infill.json"))
        outs.append((read_bvh(tmp_path / name / f"{name}_filled.bvh").global_positions(), info["gaps_ood"]))
    np.testing.assert_array_equal(outs[0][0], outs[1][0])
    assert outs[0][1] == outs[1][1]


def _swapped(tmp_path, lo, hi):
    """The raw 120 Hz validation walk 12_02 written as it is and with frames lo..hi-1 swapped for the walk played
    backwards: two BVH paths."""
    raw = os.path.join(SHARED_DATA, "cmu_bvh", "12_02.bvh")
    if not os.path.isfile(raw):
        pytest.skip("raw CMU BVH not found")
    m = read_bvh(raw)
    lq, lp = np.array(m.local_quats), np.array(m.local_pos)
    lq[lo:hi], lp[lo:hi] = lq[::-1][lo:hi], lp[::-1][lo:hi]
    write_bvh(tmp_path / "captured.bvh", m)
    write_bvh(tmp_path / "broken.bvh", dataclasses.replace(m, local_quats=lq, local_pos=lp))
    return tmp_path / "captured.bvh", tmp_path / "broken.bvh"


def test_scvae_cli_output_is_the_same_whatever_lies_between_the_keyframes(tmp_path, capsys):
    """Keyframes at file frames 401 and 483 (120 Hz; converted frames 100 and 121), two samples: the frames between
    them do not change the output (before: up to 13 cm, through the start keyframe's foot contacts)."""
    files = _swapped(tmp_path, 402, 483)
    outs = []
    for path in files:
        out = tmp_path / ("out_" + path.stem)
        assert main(["infill", "--model", "scvae", "--start", f"{path}:401", "--end", f"{path}:483", "--frames", "20",
                     "--samples", "2", "--out", str(out)]) == 0, capsys.readouterr().err
        outs.append([read_bvh(out / f).global_positions() for f in sorted(os.listdir(out)) if f.endswith(".bvh")])
    assert len(outs[0]) == 2
    for a, b in zip(*outs):
        np.testing.assert_array_equal(a, b)


def test_keyframe_contacts_read_their_own_side():
    """A start keyframe's contacts come from the step into it, an end keyframe's from the step out of it; with no
    such frame, feet count as still."""
    from inbetween_jax.data.datasets import GENERIC_CONTACT_VELFACTOR
    from inbetween_jax.models.scvae.features import keyframe_contacts
    walk = [m for m in load_motions("cmu", "val-subjects") if os.path.basename(str(m.source)) == "12_02.bvh"][0]
    vf = GENERIC_CONTACT_VELFACTOR
    for f in range(2, 28):
        before = walk.slice(0, f + 1)                       # nothing after the start keyframe f
        np.testing.assert_array_equal(keyframe_contacts(before, f, vf, "start"),
                                      keyframe_contacts(walk, f, vf, "start"))
        after = walk.slice(f, 60)                           # nothing before the end keyframe
        np.testing.assert_array_equal(keyframe_contacts(after, 0, vf, "end"), keyframe_contacts(walk, f, vf, "end"))
    assert keyframe_contacts(walk, 0, vf, "start").tolist() == [1.0] * 4                # the file's first frame
    assert keyframe_contacts(walk, walk.num_frames - 1, vf, "end").tolist() == [1.0] * 4  # and its last
    moving = [keyframe_contacts(walk, f, vf, "start") for f in range(1, 60)]
    assert 0 < np.mean(moving) < 1                          # a walk: some feet move, some stand


def test_interaction_cli_output_is_the_same_whatever_lies_between_context_and_keypose(tmp_path, capsys):
    """Both dancers of salsa take 01 (context up to frame 100, keypose at 131): the frames between do not change
    either dancer's two samples."""
    pairs = os.path.join(SHARED_DATA, "cmu_pairs")
    if not os.path.isfile(os.path.join(pairs, "60_01_scaled.bvh")):
        pytest.skip("CMU salsa pairs not found")
    for who in ("60", "61"):
        m = read_bvh(os.path.join(pairs, f"{who}_01_scaled.bvh"))
        write_bvh(tmp_path / f"{who}_captured.bvh", m)
        lq, lp = np.array(m.local_quats), np.array(m.local_pos)
        lq[101:131], lp[101:131] = lq[::-1][101:131], lp[::-1][101:131]
        write_bvh(tmp_path / f"{who}_broken.bvh", dataclasses.replace(m, local_quats=lq, local_pos=lp))
    outs = []
    for kind in ("captured", "broken"):
        a, b, out = tmp_path / f"60_{kind}.bvh", tmp_path / f"61_{kind}.bvh", tmp_path / f"out_{kind}"
        assert main(["infill", "--model", "interaction", "--a", f"{a}:100", "--b", f"{b}:100", "--key-a", f"{a}:131",
                     "--key-b", f"{b}:131", "--frames", "30", "--samples", "2", "--out", str(out)]) == 0, \
            capsys.readouterr().err
        outs.append([read_bvh(out / f).global_positions() for f in sorted(os.listdir(out)) if f.endswith(".bvh")])
    assert len(outs[0]) == 4
    for x, y in zip(*outs):
        np.testing.assert_array_equal(x, y)
