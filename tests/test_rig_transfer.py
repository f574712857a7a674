"""``data.rig_transfer.transfer_rig`` and ``experiments/retarget_mb31.py``: a real 31-joint CMU capture put on
the 43-joint training body, checked against the capture's own bone directions and hip sockets, and read back as a
file the ``cmu`` source takes; a real LaFAN1 capture (three spine joints, no fingers) and the same under
Mixamo-style names take the same route."""
import importlib.util
import os

import numpy as np
import pytest

from conftest import ROOT, SHARED_DATA
from inbetween_jax.data import read_bvh
from inbetween_jax.data.rig_transfer import (MB_UNIT_CM, SWING, canonical_names, on_31_joint_rig, rig_profile,
                                             transfer_rig)
from inbetween_jax.errors import UserError

MB31 = os.path.join(SHARED_DATA, "cmu_more", "mb31")
TEMPLATE = os.path.join(SHARED_DATA, "cmu_bvh", "02_01.bvh")      # the 43-joint body of cmu_bvh / daz43
pytestmark = pytest.mark.skipif(not os.path.isdir(MB31), reason="cmu_more/mb31 not found beside the repository")


def _script():
    spec = importlib.util.spec_from_file_location("retarget_mb31", os.path.join(ROOT, "experiments",
                                                                                "retarget_mb31.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_retargeted_bones_point_where_the_captures_do(tmp_path):
    rt = _script()
    capture = read_bvh(os.path.join(MB31, "05_03.bvh"), 0, 60)      # modern dance, arms moving
    template = read_bvh(TEMPLATE, 0, 2)
    out = transfer_rig(capture, template)
    assert out.num_frames == 59 and out.skeleton.names == template.skeleton.names      # T-pose frame 0 dropped
    _bones_follow(out, capture, 1)
    g = out.global_positions()
    cap = capture.global_positions()[1:] * MB_UNIT_CM
    names, cnames = list(out.skeleton.names), list(capture.skeleton.names)
    # the hip sockets follow the capture's (scaled by the leg-length ratio): feet stay on the floor
    sockets = 0.5 * (g[:, names.index("rThigh")] + g[:, names.index("lThigh")])
    cap_sockets = 0.5 * (cap[:, cnames.index("RightUpLeg")] + cap[:, cnames.index("LeftUpLeg")])
    ratio = np.linalg.norm(sockets, axis=-1) / np.linalg.norm(cap_sockets, axis=-1)
    assert np.ptp(ratio) < 1e-9 and 0.7 < ratio[0] < 1.3
    feet = g[:, [names.index("lFoot"), names.index("rFoot")], 1]
    assert 0.0 < feet.min() < 15.0
    # written and read back on the template's rig, as the cmu source reads it
    assert rt.main([MB31, str(tmp_path), "--template", TEMPLATE, "--only", "05_03.bvh"]) == 0
    back = read_bvh(tmp_path / "05_03.bvh")
    whole = read_bvh(os.path.join(MB31, "05_03.bvh")).num_frames
    assert back.skeleton.names == template.skeleton.names and back.num_frames == whole - 1
    np.testing.assert_allclose(back.global_positions()[:59], g, atol=1e-3)


def _bones_follow(out, capture, first):
    """The swing-aligned bones of ``out`` point along the capture's (frames ``first:``), under any naming; returns
    how many bones were compared."""
    g = out.global_positions()
    cap = capture.global_positions()[first:]
    names = list(out.skeleton.names)
    cnames = canonical_names(capture.skeleton.names, rig_profile(capture.skeleton.names))
    compared = 0
    for joint, (child, (a, b)) in SWING.items():
        if child in names and a in cnames and b in cnames:
            compared += 1
            mine = _unit(g[:, names.index(child)] - g[:, names.index(joint)])
            theirs = _unit(cap[:, cnames.index(b)] - cap[:, cnames.index(a)])
            assert np.min(np.sum(mine * theirs, -1)) > 1 - 1e-9, joint
    return compared


def test_the_asf_named_31_joint_files_take_the_same_route():
    """cmu_bvh/16_01 is the mb31 hierarchy under CMU's ASF names: the name map gives an mb31 file's joints in
    the same order with the same parents, and the capture goes on the body with every frame (it has no
    T-pose frame 0, unlike the cgspeed files)."""
    asf = read_bvh(os.path.join(SHARED_DATA, "cmu_bvh", "16_01.bvh"))
    mb = read_bvh(os.path.join(MB31, "05_03.bvh"), 0, 2)
    assert canonical_names(asf.skeleton.names, "cmu-asf") == list(mb.skeleton.names)
    assert tuple(asf.skeleton.parents) == tuple(mb.skeleton.parents)
    assert on_31_joint_rig(asf.skeleton.names) and not on_31_joint_rig(read_bvh(TEMPLATE, 0, 2).skeleton.names)
    out = transfer_rig(asf, read_bvh(TEMPLATE, 0, 2))
    assert out.num_frames == asf.num_frames == 322
    assert _bones_follow(out, asf, 0) == len(SWING) - 2     # every swung bone whose child the body has
    feet = out.global_positions()[:, [out.skeleton.names.index(n) for n in ("lFoot", "rFoot")], 1]
    assert 0.0 < feet.min() < 15.0


def test_a_capture_on_another_rig_is_refused_in_one_line():
    """A rig whose hands no name says (``lHand`` -> ``bone_12``) is neither a known rig nor readable by roles."""
    import dataclasses
    template = read_bvh(TEMPLATE, 0, 2)
    names = tuple("bone_12" if n == "lHand" else n for n in template.skeleton.names)
    other = dataclasses.replace(template, skeleton=dataclasses.replace(template.skeleton, names=names))
    with pytest.raises(UserError, match="02_01.bvh: not a rig known to the bone-direction transfer") as err:
        transfer_rig(other, template)
    assert "\n" not in str(err.value)


LAFAN1_WALK = os.path.join(SHARED_DATA, "lafan1", "walk4_subject1.bvh")


@pytest.mark.skipif(not os.path.isfile(LAFAN1_WALK), reason="lafan1/ not found beside the repository")
def test_a_lafan1_capture_goes_on_the_body_by_the_same_bones():
    """LaFAN1's rig (Spine, Spine1, Spine2, Neck, Head; LeftToe; no fingers): its top spine joint plays the chest,
    every bone with both ends in the capture follows it, the hands keep their rest rotation below the forearms,
    and the feet reach the floor.  The same capture under Mixamo-style names (``mixamorig:`` prefix, ``ToeBase``
    toes) gives the same motion."""
    import dataclasses
    from inbetween_jax.geometry.quaternion import quat_mul, quat_inv
    capture = read_bvh(LAFAN1_WALK, 300, 360)
    template = read_bvh(TEMPLATE, 0, 2)
    assert rig_profile(capture.skeleton.names) == "spine3" and not on_31_joint_rig(capture.skeleton.names)
    out = transfer_rig(capture, template, drop_tpose=False)
    assert out.num_frames == 60 and out.skeleton.names == template.skeleton.names
    assert _bones_follow(out, capture, 0) == len(SWING) - 4      # no finger joint: the hands are not swung
    names = list(out.skeleton.names)
    from inbetween_jax.geometry.kinematics import forward_kinematics
    glob = forward_kinematics(out.local_quats, out.local_pos, out.skeleton.parents)[0]
    for hand, arm in (("rHand", "rForeArm"), ("lHand", "lForeArm")):
        rel = quat_mul(quat_inv(glob[:, names.index(arm)]), glob[:, names.index(hand)])
        np.testing.assert_allclose(np.abs(rel[:, 0]), 1.0, atol=1e-9)     # local rotation: identity
    g = out.global_positions()
    feet = g[:, [names.index("lFoot"), names.index("rFoot")], 1]
    assert 0.0 < feet.min() < 15.0
    cap = capture.global_positions()
    walked, moved = (np.linalg.norm(x[-1, 0, [0, 2]] - x[0, 0, [0, 2]]) for x in (cap, g))
    assert 0.7 < moved / walked < 1.3             # the root travels as the capture's (scaled by the leg ratio)
    mixamo = {"LeftToe": "LeftToeBase", "RightToe": "RightToeBase"}
    renamed = tuple("mixamorig:" + mixamo.get(n, n) for n in capture.skeleton.names)
    other = dataclasses.replace(capture, skeleton=dataclasses.replace(capture.skeleton, names=renamed))
    assert rig_profile(renamed) == "spine3"
    np.testing.assert_allclose(transfer_rig(other, template, drop_tpose=False).global_positions(), g, atol=1e-9)


@pytest.mark.skipif(not os.path.isfile(LAFAN1_WALK), reason="lafan1/ not found beside the repository")
def test_infill_takes_a_lafan1_file_with_the_shipped_weights(tmp_path):
    """``prepare`` (infill's route) puts a LaFAN1 file on the shipped checkpoint's 21 joints, every frame kept,
    keeps the file's own rig for the way back, and says so in its note; a rig whose hand no name says is still
    refused in one line."""
    import dataclasses
    from inbetween_jax.data import Skeleton
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.shipped import shipped_run
    run = shipped_run("cae")
    skel = Skeleton.from_dict(run.skeleton)
    raw = read_bvh(LAFAN1_WALK, 0, 90)
    prep = prepare(raw, LAFAN1_WALK, skel, run.fps)
    assert prep.motion.skeleton.names == skel.names and prep.motion.num_frames == 90 and prep.factor == 1.0
    assert "LaFAN1" in prep.note and "back on the file's rig" in prep.note
    assert prep.transfer == "spine3" and prep.on_other_rig and prep.full.skeleton.names == raw.skeleton.names
    names = list(raw.skeleton.names)
    names[names.index("LeftHand")] = "joint_17"          # no hand by name: neither the table nor the roles
    broken = dataclasses.replace(raw, skeleton=dataclasses.replace(raw.skeleton, names=tuple(names)))
    with pytest.raises(UserError) as err:
        prepare(broken, LAFAN1_WALK, skel, run.fps)
    assert "walk4_subject1.bvh" in str(err.value) and "\n" not in str(err.value)


def _other_middle(body, later):
    """``body`` with its frames between the first and the last replaced by ``later``'s (the same joints, another
    stretch of motion): a stand-in for a generated fill that starts and ends on the capture's own frames."""
    import dataclasses
    q, p = body.local_quats.copy(), body.local_pos.copy()
    q[1:-1], p[1:-1] = later.local_quats[1:-1], later.local_pos[1:-1]
    return dataclasses.replace(body, local_quats=q, local_pos=p)


@pytest.mark.parametrize("path, frames", [(LAFAN1_WALK, (300, 360, 900)), (os.path.join(MB31, "05_03.bvh"),
                                                                               (1, 41, 60))])
def test_a_motion_made_on_the_body_goes_back_on_the_files_rig(path, frames):
    """:func:`transfer_back`: on the frames between two known ones every bone the transfer reads points exactly
    along the body bone it was read from (the round trip's twist is restored about the bone, which leaves its
    direction alone); the known frames are the file's own.  Back from the untouched transfer, the capture comes
    back within 2 cm per joint on average (what the body does not carry, collars, lower back and hands, follows the
    known frames)."""
    from inbetween_jax.data import Skeleton
    from inbetween_jax.data.rig_transfer import INVERSE_SWING, transfer_back
    from inbetween_jax.shipped import shipped_run
    if not os.path.isfile(path):
        pytest.skip(f"{path} not found")
    a, b, other = frames
    skel = Skeleton.from_dict(shipped_run("cae").skeleton)         # the checkpoint's 21-joint body
    user = read_bvh(path, a, b)
    body = transfer_rig(user, skel, drop_tpose=False)
    made = _other_middle(body, transfer_rig(read_bvh(path, other, other + b - a), skel, drop_tpose=False))
    back = transfer_back(made, user)
    assert back.skeleton.names == user.skeleton.names and back.num_frames == user.num_frames
    np.testing.assert_array_equal(back.local_quats[[0, -1]], user.local_quats[[0, -1]])
    np.testing.assert_array_equal(back.local_pos[[0, -1]], user.local_pos[[0, -1]])
    g, gb = back.global_positions()[1:-1], made.global_positions()[1:-1]
    ucanon = canonical_names(user.skeleton.names, rig_profile(user.skeleton.names))
    bnames = list(skel.names)
    compared = 0
    for joint, (far, (bj, bc)) in INVERSE_SWING.items():
        if joint in ucanon and far in ucanon and bc in bnames:
            mine = _unit(g[:, ucanon.index(far)] - g[:, ucanon.index(joint)])
            theirs = _unit(gb[:, bnames.index(bc)] - gb[:, bnames.index(bj)])
            assert np.min(np.sum(mine * theirs, -1)) > 1 - 1e-9, joint
            compared += 1
    assert compared >= 10
    scale = MB_UNIT_CM if "mb31" in path else 1.0
    err = np.linalg.norm(transfer_back(body, user).global_positions() - user.global_positions(), axis=-1) * scale
    assert err.mean() < 2.0 and err.max() < 8.0        # cm; collars, lower back, hands: not on the 21-joint body


@pytest.mark.skipif(not os.path.isfile(LAFAN1_WALK), reason="lafan1/ not found beside the repository")
def test_infill_writes_a_lafan1_files_fill_on_its_own_rig(tmp_path, capsys):
    """``inbetween infill --model cae`` on a LaFAN1 file with the shipped (CMU) weights: the output has the file's
    joints and frames, every frame outside the gap is the file's own, and the gap is filled."""
    import json
    from inbetween_jax.cli import main
    from inbetween_jax.data.bvh import write_bvh
    src = tmp_path / "walk.bvh"
    raw = read_bvh(LAFAN1_WALK, 0, 500)
    write_bvh(str(src), raw)
    raw = read_bvh(str(src))
    assert main(["infill", "--model", "cae", "--bvh", str(src), "--gaps", "300:360", "--out",
                 str(tmp_path / "out")]) == 0
    assert "LaFAN1" in capsys.readouterr().err
    out = read_bvh(tmp_path / "out" / "walk_filled.bvh")
    assert out.skeleton.names == raw.skeleton.names and out.num_frames == raw.num_frames
    g, want = out.global_positions(), raw.global_positions()
    np.testing.assert_allclose(g[:300], want[:300], atol=0.01)
    np.testing.assert_allclose(g[360:], want[360:], atol=0.01)
    assert np.linalg.norm(g[300:360] - want[300:360], axis=-1).mean() > 0.5
    assert json.load(open(tmp_path / "out" / "infill.json"))["gaps_ood"]


@pytest.mark.skipif(not os.path.isfile(LAFAN1_WALK), reason="lafan1/ not found beside the repository")
def test_infill_writes_an_s_cvae_transition_on_a_lafan1_files_rig(tmp_path, capsys):
    """``inbetween infill --model scvae`` between two frames of a LaFAN1 file (shipped CMU weights): the samples are
    on the file's rig, start and end on the file's own keyframes, and move between them."""
    from inbetween_jax.cli import main
    out = tmp_path / "out"
    assert main(["infill", "--model", "scvae", "--start", f"{LAFAN1_WALK}:300", "--end", f"{LAFAN1_WALK}:331",
                 "--frames", "30", "--samples", "2", "--out", str(out)]) == 0, capsys.readouterr().err
    raw = read_bvh(LAFAN1_WALK, 300, 332)
    for name in ("sample_00.bvh", "sample_01.bvh"):
        s = read_bvh(out / name)
        assert s.skeleton.names == raw.skeleton.names and s.num_frames == 32
        g, want = s.global_positions(), raw.global_positions()
        np.testing.assert_allclose(g[[0, -1]], want[[0, -1]], atol=0.01)
        assert np.all(np.isfinite(g)) and np.linalg.norm(g[16] - g[0], axis=-1).mean() > 0.5


# LaFAN1's joints under the names of two other common rigs (the Unreal mannequin's, and upper-case side suffixes
# with a two-word spine as in several public sets); neither is in the table of rigs, so both are read by roles
UE_NAMES = {"Hips": "pelvis", "Spine": "spine_01", "Spine1": "spine_02", "Spine2": "spine_03", "Neck": "neck_01",
            "Head": "head", **{f"{side}{a}": f"{b}_{side[0].lower()}" for side in ("Left", "Right") for a, b in (
                ("Shoulder", "clavicle"), ("Arm", "upperarm"), ("ForeArm", "lowerarm"), ("Hand", "hand"),
                ("UpLeg", "thigh"), ("Leg", "calf"), ("Foot", "foot"), ("Toe", "ball"))}}
SUFFIX_NAMES = {"Hips": "Hips", "Spine": "Spine", "Spine1": "Chest", "Spine2": "UpperChest", "Neck": "Neck",
                "Head": "Head", **{f"{side}{a}": f"{b}_{side[0]}" for side in ("Left", "Right") for a, b in (
                    ("Shoulder", "Shoulder"), ("Arm", "UpperArm"), ("ForeArm", "LowerArm"), ("Hand", "Hand"),
                    ("UpLeg", "UpperLeg"), ("Leg", "LowerLeg"), ("Foot", "Foot"), ("Toe", "Toes"))}}

# SMPL's joint names, as BVH exports of AMASS / SMPL fits write them (the ankle is the foot joint, SMPL's "Foot" the
# toe, the wrist the hand); the same with the "m_avg_" prefix of SMPL's own rig files, and SMPL-X's lower case
SMPL_NAMES = {"Hips": "Pelvis", "Spine": "Spine1", "Spine1": "Spine2", "Spine2": "Spine3", "Neck": "Neck",
              "Head": "Head", **{f"{side}{a}": f"{side[0]}_{b}" for side in ("Left", "Right") for a, b in (
                  ("Shoulder", "Collar"), ("Arm", "Shoulder"), ("ForeArm", "Elbow"), ("Hand", "Wrist"),
                  ("UpLeg", "Hip"), ("Leg", "Knee"), ("Foot", "Ankle"), ("Toe", "Foot"))}}
SMPL_AVG_NAMES = {k: f"m_avg_{v}" for k, v in SMPL_NAMES.items()}
SMPLX_NAMES = {k: v.lower().replace("l_", "left_").replace("r_", "right_") for k, v in SMPL_NAMES.items()}


@pytest.mark.skipif(not os.path.isfile(LAFAN1_WALK), reason="lafan1/ not found beside the repository")
@pytest.mark.parametrize("rename", [UE_NAMES, SUFFIX_NAMES, SMPL_NAMES, SMPL_AVG_NAMES, SMPLX_NAMES],
                         ids=["unreal", "suffix", "smpl", "smpl-m-avg", "smplx"])
def test_a_rig_outside_the_table_is_read_by_its_joints_roles(rename):
    """The same LaFAN1 capture under other names: :func:`rig_of` reads the roles from words and hierarchy (sides,
    hands, feet, where the arms' and legs' chains meet), and the transfer there and back is the table's, exactly."""
    import dataclasses
    from inbetween_jax.data import Skeleton
    from inbetween_jax.data.rig_transfer import rig_of, transfer_back
    from inbetween_jax.shipped import shipped_run
    capture = read_bvh(LAFAN1_WALK, 300, 360)
    names = tuple(rename[n] for n in capture.skeleton.names)
    other = dataclasses.replace(capture, skeleton=dataclasses.replace(capture.skeleton, names=names))
    profile, alias = rig_of(other.skeleton)
    assert profile == "roles" and rig_profile(names) is None
    table, roles = canonical_names(capture.skeleton.names, "spine3"), canonical_names(names, profile, alias)
    used = [b for b in roles if not b.endswith("(unused)")]
    assert len(used) == 19 and [a for a, b in zip(table, roles) if not b.endswith("(unused)")] == used
    skel = Skeleton.from_dict(shipped_run("cae").skeleton)
    want = transfer_rig(capture, skel, drop_tpose=False)
    got = transfer_rig(other, skel, drop_tpose=False)
    np.testing.assert_array_equal(got.local_quats, want.local_quats)
    np.testing.assert_array_equal(got.local_pos, want.local_pos)
    np.testing.assert_array_equal(transfer_back(got, other).local_quats, transfer_back(want, capture).local_quats)
