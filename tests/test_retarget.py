"""Users' BVH on a larger rig or at another frame rate than the checkpoint's (``inbetween_jax.data.retarget``).

Reference: the shipped 21-joint 30 Hz clip ``assets/cmu30/02_01.bvh`` was made from the raw 43-joint 120 Hz CMU
file by dropping finger and eye joints (leaves) and keeping every 4th frame, written with 4 decimals.
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest

from conftest import CLIP_A, LAFAN1_DIR, SHARED_DATA
from inbetween_jax.cli import main
from inbetween_jax.data import read_bvh
from inbetween_jax.data.retarget import expand, match_joints, prepare, restrict
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.errors import UserError
from inbetween_jax.geometry import forward_kinematics

# the raw CMU files: beside $LAFAN1_DIR's folder when it is set, else in the shared data folder
_CMU = next((d for d in (os.path.join(os.path.dirname(os.path.abspath(LAFAN1_DIR)), "cmu_bvh"),
                         os.path.join(SHARED_DATA, "cmu_bvh")) if os.path.isdir(d)), "")
RAW = os.path.join(_CMU, "02_01.bvh")                               # 43 joints, 120 Hz, 344 frames
ASF = os.path.join(_CMU, "16_01.bvh")                               # 31 joints, CMU ASF names
needs_raw = pytest.mark.skipif(not (os.path.isfile(RAW) and os.path.isfile(ASF)), reason="raw CMU BVH not found")


def world(m):
    return forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)


@needs_raw
def test_restrict_and_resample_match_the_embedded_clip():
    raw, ref = read_bvh(RAW), read_bvh(CLIP_A)
    assert raw.skeleton.num_joints == 43 and round(raw.fps) == 120 and ref.skeleton.num_joints == 21
    prep = prepare(raw, "02_01.bvh", ref.skeleton, 30.0)
    assert prep.note == "02_01.bvh: 120 fps resampled to the checkpoint's 30 fps; 22 extra joints follow by interpolation"
    m = prep.motion
    assert m.skeleton.same_topology(ref.skeleton) and m.num_frames == ref.num_frames == 86
    assert abs(m.frame_time - 1 / 30) < 1e-9 and prep.ratio == 0.25
    np.testing.assert_allclose(world(m)[1], world(ref)[1], atol=2e-4)     # 4-decimal file: ~1e-4 cm
    # the same joints of the full-rig resampled motion, independently of restrict
    full_pos = world(prep.full)[1][:, list(prep.match.user)]
    np.testing.assert_allclose(full_pos, world(ref)[1], atol=2e-4)
    np.testing.assert_allclose(full_pos, world(raw)[1][::4][:, list(prep.match.user)], atol=1e-9)


@needs_raw
def test_skipped_joint_keeps_world_orientations():
    """A checkpoint rig without ``chest``: ``neck`` and the collars take chest's rotation composed in, so their
    world orientations are the user's; expand undoes it (chest slerped across the unknown frames)."""
    raw = read_bvh(RAW).slice(0, 80)
    s = raw.skeleton
    keep = [i for i, n in enumerate(s.names) if n != "chest"]
    remap = {o: k for k, o in enumerate(keep)}
    chest = s.index("chest")
    par = tuple(-1 if s.parents[i] < 0 else remap[s.parents[i] if s.parents[i] != chest else s.parents[chest]]
                for i in keep)
    ck = Skeleton(tuple(s.names[i] for i in keep), par, s.offsets[keep], tuple(s.channels[i] for i in keep))
    match = match_joints(s, ck, "raw.bvh")
    assert match.extra == (chest,) and match.chains[ck.index("neck")] == (chest,)
    m = restrict(raw, match, ck)
    gq_user, _ = world(raw)
    gq = world(m)[0]
    dots = np.abs(np.sum(gq * gq_user[:, keep], axis=-1))
    assert dots.min() > 1 - 1e-9
    known = np.ones(80, bool)
    known[20:50] = False
    back = expand(m, raw, match, known)
    dots = np.abs(np.sum(world(back)[0][:, keep] * gq_user[:, keep], axis=-1))
    assert dots.min() > 1 - 1e-9                                         # matched joints: same world orientation
    assert np.array_equal(back.local_quats[known], raw.local_quats[known])
    moved = np.abs(back.local_quats[20:50, chest] - raw.local_quats[20:50, chest]).max()
    assert moved > 1e-3                                                   # chest itself interpolated, not copied


@needs_raw
def test_missing_joints_one_line():
    """A rig lacking the checkpoint's joints by name is refused in one line.  (CMU's own 31-joint rig, ``16_01``,
    is not: it takes the training captures' route, ``tests/test_infill_units.py``; so one of its joints is renamed
    here.)"""
    asf, ref = read_bvh(ASF), read_bvh(CLIP_A)
    assert prepare(asf, "16_01.bvh", ref.skeleton, 30.0).motion.skeleton.names == ref.skeleton.names
    names = list(asf.skeleton.names)
    names[names.index("lfemur")] = "lthighbone"
    asf = dataclasses.replace(asf, skeleton=dataclasses.replace(asf.skeleton, names=tuple(names)))
    with pytest.raises(UserError) as e:
        prepare(asf, "16_01.bvh", ref.skeleton, 30.0)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("16_01.bvh: skeleton lacks ")
    assert "abdomen, chest, neck" in msg and msg.endswith(", ...")       # at most eight names listed
    assert len(msg.split(": ", 2)[2].split(", ")) == 9


@needs_raw
def test_cae_infill_on_raw_120hz_43_joint_file(cli_runs, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["infill", "--model", "cae", "--ckpt", cli_runs["cae"], "--bvh", RAW, "--gaps", "40:120,200:240",
               "--out", str(out)])
    printed, err = capsys.readouterr()
    assert rc == 0, err
    assert "02_01.bvh: 120 fps resampled to the checkpoint's 30 fps; 22 extra joints follow by interpolation" \
        in printed + err
    raw = read_bvh(RAW)
    m = read_bvh(out / "02_01_filled.bvh")
    assert m.skeleton.names == raw.skeleton.names and abs(m.frame_time - 1 / 30) < 1e-6 and m.num_frames == 86
    known = np.ones(86, bool)
    known[10:30] = known[50:60] = False                                   # 40:120 -> 10:30, 200:240 -> 50:60
    src = world(raw)[1][::4]
    gp = world(m)[1]
    np.testing.assert_allclose(gp[known], src[known], atol=1e-3)
    assert np.all(np.isfinite(gp)) and np.abs(gp[~known] - src[~known]).max() > 1e-3
    assert np.load(out / "02_01_filled.npy").shape == (86, 21, 3)
