"""Blender's own BVH importer sees the joint world positions of our FK in the BVH files we write.

Each BVH file (written by :func:`inbetween_jax.data.write_bvh` from real mocap, and by ``inbetween infill``)
is imported headless by ``tests/blender_harness.py`` (``io_anim_bvh``, scale 1, forward -Z / up Y, native
Euler orders); every bone head of every frame, mapped back to the file's Y-up axes, must equal our
``forward_kinematics`` joint position to 1e-3 of the file's unit (0.01 mm for centimetre files, 1.3 mm for
the 1/128-unit salsa files: far below 1e-3 of the skeletons' heights), and every End-Site bone tail our
End Site.  Skipped where ``blender`` is not on PATH.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import HAS_LAFAN1, LAFAN1_DIR, SHARED_DATA
from inbetween_jax.data import read_bvh, write_bvh
from inbetween_jax.geometry import forward_kinematics, quat_rotate

pytestmark = pytest.mark.skipif(shutil.which("blender") is None, reason="blender not on PATH")

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
HARNESS = os.path.join(HERE, "blender_harness.py")
ASSETS = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30")
# the shared data folder, or the one holding $LAFAN1_DIR when that is set
SALSA = next((p for p in (os.path.join(d, "cmu_pairs", "60_12_scaled.bvh")
                          for d in (SHARED_DATA, os.path.dirname(os.path.abspath(LAFAN1_DIR))))
              if os.path.exists(p)), None)
TOL = 1e-3                     # in the file's unit


def _cli_infill_files(request, out) -> dict:
    """BVH files written by the ``inbetween infill`` command, on the tiny run folders of the CLI tests.

    The runs come from the ``cli_runs`` fixture (made once per test session, shared with the CLI tests); making
    them compiles three models, so this is called lazily, by the slow cases only.
    """
    from inbetween_jax.cli import main
    from conftest import CLIP_A, CLIP_B
    runs = request.getfixturevalue("cli_runs")
    cae_out, scvae_out = out / "cli_cae", out / "cli_scvae"
    assert main(["infill", "--model", "cae", "--ckpt", runs["cae"], "--bvh", CLIP_A, "--gaps", "10:30",
                 "--out", str(cae_out)]) == 0
    assert main(["infill", "--model", "scvae", "--ckpt", runs["scvae"], "--start", f"{CLIP_A}:5",
                 "--end", f"{CLIP_B}:40", "--frames", "10", "--out", str(scvae_out)]) == 0
    return {"cli_cae": cae_out / "02_01_filled.bvh", "cli_scvae": scvae_out / "sample_00.bvh"}


@pytest.fixture(scope="module")
def written_bvh_files(tmp_path_factory, request) -> dict:
    """``{case: path, or a function returning it}`` of the BVH files to check; a case is absent when its
    data are missing.  The CLI's files are functions: they are made on first use, by the slow cases only."""
    out = tmp_path_factory.mktemp("blender_bvh")
    files = {}

    # 1. Real mocap re-written by our writer (short clips: Blender imports them in a few seconds).
    def write(case, motion):
        files[case] = out / f"{case}.bvh"
        write_bvh(files[case], motion)
    write("cmu30", read_bvh(os.path.join(ASSETS, "02_01.bvh"), 20, 50))                  # 30 frames, cm
    if HAS_LAFAN1:
        write("lafan1", read_bvh(os.path.join(LAFAN1_DIR, "dance1_subject1.bvh"), 1000, 1040))   # 40, cm
    if SALSA:         # 1/128 unit, root ZYX and joints ZXY; 120 Hz -> every 4th frame
        write("salsa", read_bvh(SALSA, 600, 720).slice(0, None, 4))                     # 30 frames

    # 2. Files written by the CLI's infill command, made on first use (the tiny runs compile three models).
    made = {}

    def cli_files():
        if not made:
            made.update(_cli_infill_files(request, out))
        return made
    files.update({k: (lambda k=k: cli_files()[k]) for k in ("cli_cae", "cli_scvae")})
    return files


def blender_import(bvh, out_json) -> dict:
    """Run the harness in a headless Blender; returns its JSON (see ``blender_harness.py``)."""
    res = subprocess.run(["blender", "--background", "--factory-startup", "--python-exit-code", "1",
                          "--python", HARNESS, "--", str(bvh), str(out_json)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, f"blender failed on {bvh}:\n{res.stdout[-2000:]}\n{res.stderr[-2000:]}"
    with open(out_json) as f:
        return json.load(f)


@pytest.mark.parametrize("case", ["cmu30", "lafan1", "salsa", pytest.param("cli_cae", marks=pytest.mark.slow),
                                  pytest.param("cli_scvae", marks=pytest.mark.slow)])
def test_blender_joint_positions_match_ours(written_bvh_files, case, tmp_path, record_property):
    if case not in written_bvh_files:
        pytest.skip(f"no data for {case!r} (LaFAN1 / cmu_pairs not found)")
    path = written_bvh_files[case]
    path = path() if callable(path) else path
    m = read_bvh(path)
    skel = m.skeleton
    gq, gp = forward_kinematics(m.local_quats, m.local_pos, skel.parents)
    got = blender_import(path, tmp_path / "blender.json")

    # the armature: one bone per joint, same names and parents, one key per file frame
    assert got["num_frames"] == m.num_frames and got["frame_start"] == 1
    assert sorted(got["bones"]) == sorted(skel.names)
    parent_of = dict(zip(got["bones"], got["parents"]))
    assert [parent_of[n] for n in skel.names] == [skel.names[p] if p >= 0 else None for p in skel.parents]

    # bone heads = joint world positions, every frame (file axes and unit)
    idx = [got["bones"].index(n) for n in skel.names]
    heads = np.asarray(got["heads"])[:, idx]                      # (T, J, 3)
    err = float(np.abs(heads - gp).max())
    record_property("max_head_error", err)
    print(f"\n{case}: {m.num_frames} frames x {skel.num_joints} joints, max |Blender - ours| = {err:.2e} "
          f"(file unit; skeleton height {np.ptp(gp[0, :, 1]):.3g})", file=sys.stderr)
    np.testing.assert_allclose(heads, gp, rtol=0, atol=TOL)
    # the clip is animated (not compared in the rest pose only): joints move far more than the tolerance
    assert np.abs(gp - gp[:1]).max() > 100 * TOL

    # End Sites become the tails of their joints' bones where Blender keeps them (one End Site, >= 1e-3 long;
    # LaFAN1's End Sites all have zero offsets, so Blender makes those tails up)
    ends = [(p, o) for p, o in skel.end_sites if np.linalg.norm(o) > 2e-3
            and sum(q == p for q, _ in skel.end_sites) == 1]
    if not ends:
        return
    tails = np.asarray(got["tails"])[:, [got["bones"].index(skel.names[p]) for p, _ in ends]]
    ours = np.stack([gp[:, p] + quat_rotate(gq[:, p], np.broadcast_to(o, (m.num_frames, 3))) for p, o in ends], 1)
    np.testing.assert_allclose(tails, ours, rtol=0, atol=TOL)
