"""The CAE's base in global positions where the body stays near its place (models/cae/global_base.py): the global
Hermite against straight motion and unread gap frames, the travel share against a root track of known speed, and on
real capture: the shipped CAE's shut gap in place is that fill, a walk's gap keeps the body-frame base, and on a
jump in place and on floor work the global fill is closer to the capture than the body-frame base."""
import dataclasses
import os

import numpy as np
import pytest
from conftest import LAFAN1_DIR, SHARED_DATA

from inbetween_jax.models.cae.global_base import global_fill, travel_share


def test_global_fill_keeps_a_straight_glide_and_reads_no_gap_frame():
    t = np.arange(40, dtype=np.float32)
    start = np.array([[0.0, 90.0, 0.0], [10.0, 140.0, -5.0]], np.float32)           # pure math: two joints
    velocity = np.array([[1.5, 0.0, -0.5], [0.2, 0.3, 0.0]], np.float32)
    glide = start[None] + t[:, None, None] * velocity[None]                         # (T, J, 3), constant velocity
    mask = np.ones(40, np.float32)
    mask[12:30] = 0.0
    out = global_fill(glide, mask, 0.3)
    np.testing.assert_allclose(out, glide, atol=1e-4)                               # a straight glide stays one
    noisy = glide.copy()
    noisy[12:30] += 50.0                                                            # gap frames: never read
    np.testing.assert_array_equal(global_fill(noisy, mask, 0.3), out)
    bent = glide.copy()
    bent[:12, 0, 1] += np.linspace(-6.0, 0.0, 12)                                   # joint 0 rises into the gap
    filled = global_fill(bent, mask, 0.3)
    np.testing.assert_array_equal(filled[mask > 0.5], bent[mask > 0.5])             # known frames unchanged
    assert filled[12, 0, 1] > bent[11, 0, 1]                                        # ... and keeps rising


def test_travel_share_is_one_near_zero_far_and_linear_between():
    for speed, expected in ((0.0, 1.0), (0.5, 1.0), (1.0, 0.5), (1.2, 0.3), (2.0, 0.0), (5.0, 0.0)):
        ref = np.stack([np.arange(100) * speed, np.zeros(100)], axis=1)            # cm, `speed` cm per frame
        share = travel_share(ref, 40, 80, 0.2, 0.6)                                 # travel = speed x 40 frames
        assert share == pytest.approx(expected, abs=1e-9), speed


@pytest.fixture(scope="module")
def jumps_in_place():
    """``(run, motion)``: the shipped CAE and CMU 16_01 (jumps in place, 31-joint rig, 30 Hz) as infill reads it."""
    from inbetween_jax.data import Skeleton, read_bvh
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.shipped import shipped_run
    path = os.path.join(SHARED_DATA, "cmu_bvh", "16_01.bvh")
    if not os.path.exists(path):
        pytest.skip("needs ../shared/data/cmu_bvh")
    run = shipped_run("cae")
    return run, prepare(read_bvh(path), path, Skeleton.from_dict(run.skeleton), run.fps).motion


def test_shipped_gap_in_place_is_the_global_hermite_and_a_walk_keeps_its_base(jumps_in_place, cae_fast_walk):
    from inbetween_jax.models.cae.infer import load, process_motion
    from inbetween_jax.models.cae.masks import gap_frames
    from inbetween_jax.shipped import config_with_overrides
    run, motion = jumps_in_place
    model = load(run)
    mc = model.cfg.model
    assert mc.global_base_far > 0                                       # on in the shipped weights
    gap = (40, 70)
    res = process_motion(model, motion, [gap])
    row = res["gaps_ood"][0]
    assert row["gate_weight"] == 0.0 and row.get("match_weight", 0.0) == 0.0     # the body barely travels
    assert row["global_share"] == 1.0 and row["global_weight"] == 1.0
    fm = gap_frames(motion.num_frames, [gap])
    want = global_fill(motion.global_positions(), fm, mc.global_base_fade)
    np.testing.assert_allclose(res["positions"][40:70], want[40:70], atol=1e-3)
    walk_run, walk = cae_fast_walk                                      # a walk at 1.2 m/s: 1.2 m a second
    on = process_motion(load(walk_run), walk, [(20, 50)])
    off_run = dataclasses.replace(walk_run, config=config_with_overrides("cae", walk_run.config,
                                                                           ["model.global_base_far=0"]))
    off = process_motion(load(off_run), walk, [(20, 50)])
    assert on["gaps_ood"][0]["global_share"] == 0.0
    np.testing.assert_array_equal(on["positions"], off["positions"])


def _base_errors(model, motion, gaps):
    """Per gap: the error (cm) of the body-frame base and of the global Hermite, both as the run builds them."""
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.models.cae.global_base import base_positions
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    body_model = dataclasses.replace(model.cfg.model, global_base_far=0.0)
    model.cfg = dataclasses.replace(model.cfg, model=body_model)          # base_positions: the body-frame base
    out = []
    for a, b in gaps:
        fm = gap_frames(motion.num_frames, [(a, b)])
        feats = body_frame_features(motion, known=fm > 0.5)
        mask = frame_mask_image(fm, model.num_joints)
        xm = model.normalizer(feats.features).T.astype(np.float32) * mask
        body = base_positions(model, xm, mask, feats, fm)
        glob = global_fill(feats.global_pos, fm, body_model.global_base_fade)
        truth = feats.global_pos[a:b]
        out.append([float(np.linalg.norm(f[a:b] - truth, axis=-1).mean()) for f in (body, glob)])
    return np.array(out)


def test_global_fill_beats_the_body_frame_base_in_place_and_on_the_floor(jumps_in_place):
    """Validation subject 16's jumps in place (1-s gaps), and a LaFAN1 fall and get-up where the body lies on the
    floor, so its facing is ill-defined and the body-frame fill swings the limbs around it (measured in
    docs/results/gate.md, "global base")."""
    from inbetween_jax.data import Skeleton, read_bvh
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.models.cae.infer import load
    run, motion = jumps_in_place
    model = load(run)
    jumps = _base_errors(model, motion, [(a, a + 30) for a in range(10, motion.num_frames - 40, 30)])
    ratio = jumps[:, 1] / jumps[:, 0]                                   # 1-s gaps every second
    assert len(ratio) >= 8 and ratio.mean() < 0.97 and (ratio < 1.0).mean() >= 0.7, ratio
    path = os.path.join(LAFAN1_DIR, "fallAndGetUp1_subject1.bvh")
    if not os.path.exists(path):
        pytest.skip("needs ../shared/data/lafan1")
    fall = prepare(read_bvh(path), path, Skeleton.from_dict(run.skeleton), run.fps).motion
    floor = _base_errors(load(run), fall, [(190, 220), (220, 250)])      # lying down, rolling over
    assert (floor[:, 1] < 0.5 * floor[:, 0]).all(), floor                # 4.4 against 22.0 cm
