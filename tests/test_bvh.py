"""BVH reading / writing on real files, and one clear error per kind of malformed input."""
import os
import stat

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from inbetween_jax.data import BVHError, read_bvh, write_bvh
from inbetween_jax.data.bvh import motion_to_channels
from inbetween_jax.data.datasets import EMBEDDED_DIR
from inbetween_jax.geometry import forward_kinematics

from conftest import LAFAN1_DIR, requires_lafan1

CMU_FILE = os.path.join(EMBEDDED_DIR, "02_01.bvh")


def raw_channels(path):
    """The MOTION numbers of a BVH file, parsed with nothing but str.split."""
    lines = open(path).read().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.strip() == "MOTION")
    return np.array([ln.split() for ln in lines[i + 3:] if ln.strip()], dtype=np.float64)


def test_embedded_file_reads_and_matches_scipy_euler():
    m = read_bvh(CMU_FILE)
    assert m.skeleton.num_joints == 21 and m.local_quats.shape == (m.num_frames, 21, 4)
    assert abs(m.fps - 30.0) < 1e-3
    raw = raw_channels(CMU_FILE)
    np.testing.assert_allclose(m.root_pos, raw[:, :3], atol=1e-12)
    # joint 1 (abdomen) has "Zrotation Xrotation Yrotation" at columns 6..8
    assert m.skeleton.channels[1] == ("Zrotation", "Xrotation", "Yrotation")
    ref = Rotation.from_euler("ZXY", raw[:, 6:9], degrees=True).as_quat(scalar_first=True)
    assert np.allclose(np.abs(np.sum(ref * m.local_quats[:, 1], -1)), 1, atol=1e-12)


@requires_lafan1
def test_lafan1_roundtrip_exact(tmp_path):
    src = os.path.join(LAFAN1_DIR, "obstacles1_subject5.bvh")
    m = read_bvh(src, 0, 400)
    assert m.skeleton.num_joints == 22
    assert m.skeleton.foot_joints() == (3, 4, 7, 8)
    np.testing.assert_allclose(motion_to_channels(m), raw_channels(src)[:400], atol=1e-9)
    out = tmp_path / "copy.bvh"
    write_bvh(out, m)
    m2 = read_bvh(out)
    np.testing.assert_allclose(motion_to_channels(m2), motion_to_channels(m), atol=1e-4)
    _, p1 = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)
    _, p2 = forward_kinematics(m2.local_quats, m2.local_pos, m2.skeleton.parents)
    np.testing.assert_allclose(p2, p1, atol=1e-4)


def test_any_channel_order_roundtrip(tmp_path):
    """A hand-written skeleton with a different Euler order per joint and position channels on a child."""
    text = """HIERARCHY
ROOT root
{
  OFFSET 0 0 0
  CHANNELS 6 Zposition Xposition Yposition Yrotation Xrotation Zrotation
  JOINT a
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Zrotation Yrotation
    JOINT b
    {
      OFFSET 0 0 5
      CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
      End Site
      {
        OFFSET 1 0 0
      }
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.05
1 2 3 10 20 30 40 50 60 0 0 5 -10 -20 -30
1.5 2 3 11 21 31 41 51 61 0 0.5 5 -11 -21 -31
2 2 3 12 22 32 42 52 62 0 1 5 -12 -22 -32
"""
    src = tmp_path / "orders.bvh"
    src.write_text(text)
    m = read_bvh(src)
    assert [m.skeleton.rotation_order(j) for j in range(3)] == ["yxz", "xzy", "zyx"]
    np.testing.assert_allclose(m.root_pos[1], [2.0, 3.0, 1.5])  # Z X Y order in the file
    np.testing.assert_allclose(m.local_pos[2, 2], [0.0, 1.0, 5.0])
    ref = Rotation.from_euler("XZY", [40, 50, 60], degrees=True).as_quat(scalar_first=True)
    assert abs(abs(np.dot(ref, m.local_quats[0, 1])) - 1) < 1e-12
    write_bvh(tmp_path / "out.bvh", m)
    np.testing.assert_allclose(raw_channels(tmp_path / "out.bvh"), raw_channels(src), atol=1e-4)


GOOD_HEAD = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Leg
  {
    OFFSET 0 -10 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 -10 0
    }
  }
}
MOTION
"""
ROW = "0 90 0 0 0 0 10 0 0"

BAD_FILES = {
    "truncated": (GOOD_HEAD + "Frames: 3\nFrame Time: 0.0333\n" + ROW + "\n" + ROW + "\n", 20, "truncated MOTION"),
    "wrong_count": (GOOD_HEAD + "Frames: 2\nFrame Time: 0.0333\n" + ROW + "\n" + ROW + " 5\n", 20,
                    "frame has 10 values"),
    "unknown_channel": (GOOD_HEAD.replace("Zrotation Yrotation Xrotation\n    End",
                                          "Zrotation Wrotation Xrotation\n    End"), 9, "unknown channel name 'Wrotation'"),
    "non_numeric": (GOOD_HEAD + "Frames: 2\nFrame Time: 0.0333\n" + ROW + "\n0 90 0 0 abc 0 10 0 0\n", 20,
                    "non-numeric value 'abc' in column 5"),
    "zero_frames": (GOOD_HEAD + "Frames: 0\nFrame Time: 0.0333\n", 17, "Frames must be a positive integer"),
    "nan_value": (GOOD_HEAD + "Frames: 1\nFrame Time: 0.0333\n0 90 0 nan 0 0 10 0 0\n", 19, "non-finite value 'nan'"),
    "channel_count": (GOOD_HEAD.replace("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation"), 9, "CHANNELS says 4"),
    "no_motion": (GOOD_HEAD.replace("MOTION\n", ""), 15, "before the MOTION section"),
    "unbalanced": (GOOD_HEAD.replace("}\n}\nMOTION", "}\nMOTION"), 15, "MOTION before every"),
    "bad_offset": (GOOD_HEAD.replace("OFFSET 0 -10 0\n    CHANNELS", "OFFSET 0 x 0\n    CHANNELS"), 8, "non-numeric OFFSET"),
    "not_bvh": ("hello world\n", 1, "missing HIERARCHY"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_malformed_bvh_names_file_and_line(tmp_path, case):
    text, line, message = BAD_FILES[case]
    path = tmp_path / f"{case}.bvh"
    path.write_text(text)
    with pytest.raises(BVHError) as err:
        read_bvh(path)
    msg = str(err.value)
    assert "\n" not in msg and str(path) in msg and message in msg, msg
    assert err.value.line == line, msg


def test_good_header_parses(tmp_path):
    """The template used above is itself valid, so each failure is caused by its one defect."""
    path = tmp_path / "ok.bvh"
    path.write_text(GOOD_HEAD + "Frames: 2\nFrame Time: 0.0333\n" + ROW + "\n" + ROW + "\n")
    m = read_bvh(path)
    gq, gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)
    np.testing.assert_allclose(gp[0], [[0, 90, 0], [0, 80, 0]], atol=1e-12)
    ref = Rotation.from_euler("z", 10, degrees=True).as_quat(scalar_first=True)
    assert abs(abs(np.dot(gq[1, 1], ref)) - 1) < 1e-12


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(BVHError, match="missing.bvh: file not found"):
        read_bvh(tmp_path / "missing.bvh")
    with pytest.raises(BVHError, match="is a directory"):
        read_bvh(tmp_path)


def test_write_refuses_nan_and_leaves_nothing(tmp_path):
    m = read_bvh(CMU_FILE, 0, 5)
    m.local_quats[2, 3, 0] = np.nan
    out = tmp_path / "bad.bvh"
    with pytest.raises(ValueError, match="non-finite"):
        write_bvh(out, m)
    assert not out.exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002], ids=lambda m: f"umask{m:03o}")
def test_written_file_has_the_permissions_open_gives(tmp_path, mask):
    """A new file gets what ``open(path, "w")`` gives under the umask; an overwritten file keeps its mode."""
    m = read_bvh(CMU_FILE, 0, 5)
    old = os.umask(mask)
    try:
        with open(tmp_path / "by_open.txt", "w") as fh:
            fh.write("x")
        write_bvh(tmp_path / "new.bvh", m)
    finally:
        os.umask(old)
    mode = stat.S_IMODE(os.stat(tmp_path / "new.bvh").st_mode)
    assert mode == stat.S_IMODE(os.stat(tmp_path / "by_open.txt").st_mode) == 0o666 & ~mask
    os.chmod(tmp_path / "new.bvh", 0o640)
    write_bvh(tmp_path / "new.bvh", m)
    assert stat.S_IMODE(os.stat(tmp_path / "new.bvh").st_mode) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["by_open.txt", "new.bvh"]


@pytest.mark.parametrize("source", ["embedded", "lafan1"])
def test_written_bvh_read_by_independent_reader(tmp_path, source):
    """``bvhio`` (an unrelated BVH implementation) sees the same world joint positions as our FK."""
    bvhio = pytest.importorskip("bvhio")
    path = CMU_FILE if source == "embedded" else os.path.join(LAFAN1_DIR, "walk4_subject1.bvh")
    if not os.path.exists(path):
        pytest.skip("LaFAN1 not available")
    m = read_bvh(path, 0, 30)
    out = tmp_path / "written.bvh"
    write_bvh(out, m)
    _, gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)
    root = bvhio.readAsHierarchy(str(out))
    joints = [j for j, _, _ in root.layout() if j.Name in m.skeleton.names]
    assert len(joints) == m.skeleton.num_joints
    idx = [m.skeleton.index(j.Name) for j in joints]
    for frame in (0, 13, 29):
        root.loadPose(frame)
        theirs = np.array([list(j.PositionWorld) for j in joints])
        np.testing.assert_allclose(theirs, gp[frame, idx], atol=1e-3)


def test_scaled_motion_scales_every_joint_position():
    """Motion.scaled(s): world joint positions times s (offsets and local positions alike), rotations kept;
    scaling back restores the motion."""
    m = read_bvh(CMU_FILE, 0, 20)
    big = m.scaled(128.0)
    np.testing.assert_allclose(big.global_positions(), 128.0 * m.global_positions(), rtol=1e-12, atol=1e-9)
    assert np.array_equal(big.local_quats, m.local_quats) and big.skeleton.names == m.skeleton.names
    np.testing.assert_allclose(big.scaled(1 / 128.0).local_pos, m.local_pos, rtol=1e-12)
    assert not np.allclose(big.skeleton.offsets[1:], m.skeleton.offsets[1:])
