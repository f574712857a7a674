"""``inbetween infill`` converts a file in another length unit to the checkpoint's and back: a validation walk (raw
120 Hz, 43 joints, centimetres) written in metres gives the same fill, in metres, as the centimetre file, with the
same gate scores.  Before, the CAE and the S-CVAE read such a file as it was: 1/100 of the training motion's size,
a body standing still to every gate, so the learned fill was never used."""
from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from conftest import SHARED_DATA
from inbetween_jax.cli import main
from inbetween_jax.data import read_bvh
from inbetween_jax.data.bvh import write_bvh

CM_PER_M = 100.0


@pytest.fixture(scope="module")
def walk_files(tmp_path_factory):
    """The raw validation walk 12_02 written as it is (centimetres) and in metres: two BVH paths."""
    raw = os.path.join(SHARED_DATA, "cmu_bvh", "12_02.bvh")
    if not os.path.isfile(raw):
        pytest.skip("raw CMU BVH not found")
    d = tmp_path_factory.mktemp("units")
    m = read_bvh(raw)
    write_bvh(d / "walk_cm.bvh", m)
    write_bvh(d / "walk_m.bvh", m.scaled(1.0 / CM_PER_M), decimals=8)
    return d / "walk_cm.bvh", d / "walk_m.bvh"


def test_prepare_converts_to_the_checkpoints_unit(walk_files):
    from inbetween_jax.data import Skeleton
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.shipped import shipped_run
    run = shipped_run("cae")
    skel = Skeleton.from_dict(run.skeleton)
    cm, m = (prepare(read_bvh(p), str(p), skel, run.fps) for p in walk_files)
    assert cm.factor == 1.0 and m.factor == pytest.approx(CM_PER_M, rel=1e-6)
    assert "positions scaled by 100" in m.note and "scaled" not in (cm.note or "")
    np.testing.assert_allclose(m.motion.global_positions(), cm.motion.global_positions(), atol=1e-3)
    back = m.to_file_unit(m.motion)
    np.testing.assert_allclose(back.global_positions() * CM_PER_M, cm.motion.global_positions(), atol=1e-3)


def _infill(args, out, capsys):
    assert main(["infill", *args, "--out", str(out)]) == 0, capsys.readouterr().err
    info = json.load(open(out / "infill.json"))
    bvhs = sorted(f for f in os.listdir(out) if f.endswith(".bvh"))
    return [read_bvh(out / f) for f in bvhs], info


def test_cae_fills_a_file_in_metres_as_in_centimetres(walk_files, tmp_path, capsys):
    outs = [_infill(["--model", "cae", "--bvh", str(p), "--gaps", "201:322"], tmp_path / p.stem, capsys)
            for p in walk_files]
    (cm,), cm_info = outs[0]
    (m,), m_info = outs[1]
    assert m.skeleton.offsets[1] == pytest.approx(cm.skeleton.offsets[1] / CM_PER_M, abs=1e-6)   # the file's unit
    np.testing.assert_allclose(m.global_positions() * CM_PER_M, cm.global_positions(), atol=0.05)
    for a, b in zip(cm_info["gaps_ood"], m_info["gaps_ood"]):
        assert b["ood_score"] == pytest.approx(a["ood_score"], abs=1e-4)
        assert b["gate_weight"] == pytest.approx(a["gate_weight"], abs=1e-3)
    assert cm_info["gaps_ood"][0]["gate_weight"] > 0.5          # a walk: the learned fill, in both units


def test_scvae_fills_a_file_in_metres_as_in_centimetres(walk_files, tmp_path, capsys):
    outs = [_infill(["--model", "scvae", "--start", f"{p}:401", "--end", f"{p}:483", "--frames", "20"],
                    tmp_path / p.stem, capsys) for p in walk_files]
    (cm,), cm_info = outs[0]
    (m,), m_info = outs[1]
    np.testing.assert_allclose(m.global_positions() * CM_PER_M, cm.global_positions(), atol=0.05)
    assert m_info["ood_score"] == pytest.approx(cm_info["ood_score"], abs=1e-4)
    assert m_info["gate_weight"] == pytest.approx(cm_info["gate_weight"], abs=1e-3)
    assert cm_info["ood_score"] < 0.5 and cm_info["gate_weight"] > 0.0   # the keyframes say the body travels


def test_the_31_joint_cmu_rig_is_put_on_the_checkpoints_body_as_in_training(tmp_path, capsys):
    """A validation subject's capture on CMU's 31-joint rig (``16_01``: ASF names, CMU's 0.0564 m unit) was refused
    (it lacks 19 of the 21 joints by name).  Now it takes the training data's route (bone directions onto the
    43-joint body, then its 21 joints) with every frame kept, and the CAE fills it; the output goes back on the
    file's own rig, its known frames the file's own."""
    from inbetween_jax.data import Skeleton
    from inbetween_jax.data.retarget import match_joints, prepare, restrict
    from inbetween_jax.data.rig_transfer import transfer_rig
    from inbetween_jax.shipped import shipped_run
    path = os.path.join(SHARED_DATA, "cmu_bvh", "16_01.bvh")
    if not os.path.isfile(path):
        pytest.skip("raw CMU BVH not found")
    run = shipped_run("cae")
    skel = Skeleton.from_dict(run.skeleton)
    raw = read_bvh(path)
    prep = prepare(raw, path, skel, run.fps)
    assert prep.motion.num_frames == raw.num_frames and prep.motion.skeleton.names == skel.names
    assert "31-joint CMU rig" in prep.note and prep.factor == 1.0
    body = read_bvh(os.path.join(SHARED_DATA, "cmu_bvh", "02_01.bvh"), 0, 2)      # the training route's template
    trained = transfer_rig(raw, body, drop_tpose=False)
    trained = restrict(trained, match_joints(trained.skeleton, skel, path), skel)
    np.testing.assert_allclose(prep.motion.global_positions(), trained.global_positions(), atol=1e-6)
    (out,), info = _infill(["--model", "cae", "--bvh", path, "--gaps", "100:160"], tmp_path / "out", capsys)
    assert out.skeleton.names == raw.skeleton.names and out.num_frames == raw.num_frames
    g, want = out.global_positions(), raw.global_positions()
    np.testing.assert_allclose(g[:100], want[:100], atol=0.01)
    np.testing.assert_allclose(g[160:], want[160:], atol=0.01)
    assert np.linalg.norm(g[100:160] - want[100:160], axis=-1).mean() > 0.01   # the gap is filled, not copied
    assert len(info["gaps_ood"]) == 1


def test_takes_rig_transfer_needs_the_bodys_joints():
    from inbetween_jax.data import Skeleton
    from inbetween_jax.data.rig_transfer import takes_rig_transfer
    from inbetween_jax.shipped import shipped_run
    skel = Skeleton.from_dict(shipped_run("cae").skeleton)
    assert takes_rig_transfer(skel)
    names = list(skel.names)
    names[names.index("lShin")] = "lKnee"
    assert not takes_rig_transfer(dataclasses.replace(skel, names=tuple(names)))
