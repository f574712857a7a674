"""``data.rig_transfer.transfer_mb31`` and ``experiments/retarget_mb31.py``: a real 31-joint CMU capture put on
the 43-joint training body, checked against the capture's own bone directions and hip sockets, and read back as a
file the ``cmu`` source takes."""
import importlib.util
import os

import numpy as np
import pytest

from conftest import ROOT, SHARED_DATA
from inbetween_jax.data import read_bvh
from inbetween_jax.data.rig_transfer import ASF31_TO_MB31, MB_UNIT_CM, SWING, on_31_joint_rig, transfer_mb31
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
    out = transfer_mb31(capture, template)
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
    """The swing-aligned bones of ``out`` point along the capture's (frames ``first:``), under either naming."""
    g = out.global_positions()
    cap = capture.global_positions()[first:]
    names = list(out.skeleton.names)
    cnames = [ASF31_TO_MB31.get(n, n) for n in capture.skeleton.names]
    for joint, (child, (a, b)) in SWING.items():
        if child in names:
            mine = _unit(g[:, names.index(child)] - g[:, names.index(joint)])
            theirs = _unit(cap[:, cnames.index(b)] - cap[:, cnames.index(a)])
            assert np.min(np.sum(mine * theirs, -1)) > 1 - 1e-9, joint


def test_the_asf_named_31_joint_files_take_the_same_route():
    """cmu_bvh/16_01 is the mb31 hierarchy under CMU's ASF names: the name map gives an mb31 file's joints in
    the same order with the same parents, and the capture goes on the body with every frame (it has no
    T-pose frame 0, unlike the cgspeed files)."""
    asf = read_bvh(os.path.join(SHARED_DATA, "cmu_bvh", "16_01.bvh"))
    mb = read_bvh(os.path.join(MB31, "05_03.bvh"), 0, 2)
    assert [ASF31_TO_MB31[n] for n in asf.skeleton.names] == list(mb.skeleton.names)
    assert tuple(asf.skeleton.parents) == tuple(mb.skeleton.parents)
    assert on_31_joint_rig(asf.skeleton.names) and not on_31_joint_rig(read_bvh(TEMPLATE, 0, 2).skeleton.names)
    out = transfer_mb31(asf, read_bvh(TEMPLATE, 0, 2))
    assert out.num_frames == asf.num_frames == 322
    _bones_follow(out, asf, 0)
    feet = out.global_positions()[:, [out.skeleton.names.index(n) for n in ("lFoot", "rFoot")], 1]
    assert 0.0 < feet.min() < 15.0


def test_a_capture_on_another_rig_is_refused_in_one_line():
    template = read_bvh(TEMPLATE, 0, 2)
    with pytest.raises(UserError, match="02_01.bvh: not the 31-joint CMU rig") as err:
        transfer_mb31(template, template)
    assert "\n" not in str(err.value)
