"""Left-right mirror of real motion on its own rig (geometry/mirror.py, ``Motion.mirrored``), checked against
the mirror image of the original's forward-kinematics positions."""
from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest

from conftest import CLIP_A, LAFAN1_DIR, requires_lafan1
from inbetween_jax.data import read_bvh
from inbetween_jax.geometry.mirror import mirror_pose, rest_side_axis


def _reflected_twins(motion, world_axis):
    """The independent reference: every joint's FK position reflected in the world plane, left and right
    swapped."""
    flip = np.ones(3)
    flip[world_axis] = -1.0
    return motion.global_positions()[:, list(motion.skeleton.mirror_map())] * flip


@pytest.mark.parametrize("world_axis", [0, 2])
def test_mirrored_cmu_motion_is_the_mirror_image_of_its_positions(world_axis):
    m = read_bvh(CLIP_A)
    assert rest_side_axis(m.skeleton.offsets, m.skeleton.mirror_map()) == 0     # CMU: x is the side
    mm = m.mirrored(world_axis)
    np.testing.assert_allclose(mm.global_positions(), _reflected_twins(m, world_axis), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(mm.local_quats, axis=-1), 1.0, atol=1e-12)
    assert np.all(np.sum(mm.local_quats[1:] * mm.local_quats[:-1], -1) > 0)      # signs stay continuous
    back = mm.mirrored(world_axis)
    np.testing.assert_allclose(back.local_quats, m.local_quats, atol=1e-12)       # an involution
    np.testing.assert_allclose(back.local_pos, m.local_pos, atol=1e-12)


@requires_lafan1
def test_mirrored_lafan1_motion_on_a_rig_whose_side_axis_is_z():
    m = read_bvh(os.path.join(LAFAN1_DIR, "walk4_subject1.bvh"), 0, 200)
    assert rest_side_axis(m.skeleton.offsets, m.skeleton.mirror_map()) == 2
    np.testing.assert_allclose(m.mirrored().global_positions(), _reflected_twins(m, 0), atol=1e-8)


def test_rigs_without_a_mirror_are_refused():
    m = read_bvh(CLIP_A)
    twin = m.skeleton.mirror_map()
    with pytest.raises(ValueError, match="no left/right|Left"):
        rest_side_axis(m.skeleton.offsets, range(len(twin)))
    lopsided = m.skeleton.offsets.copy()
    lopsided[twin.index(next(i for i, t in enumerate(twin) if t != i))] *= 2.5     # one leg far longer
    with pytest.raises(ValueError, match="not left-right symmetric"):
        rest_side_axis(lopsided, twin)
    with pytest.raises(ValueError, match="not left-right symmetric"):
        dataclasses.replace(m, skeleton=dataclasses.replace(m.skeleton, offsets=lopsided)).mirrored()
    q, r = mirror_pose(m.local_quats[:3], m.root_pos[:3], twin, 0)
    assert q.shape == (3, m.skeleton.num_joints, 4) and r.shape == (3, 3)
