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


def _symmetric(windows):
    """The same windows on the rig made exactly left-right symmetric (each offset the mean of itself and its
    twin's reflection), so a mirror image's positions can be compared exactly."""
    twin = list(windows.skeleton.mirror_map())
    off = windows.skeleton.offsets.astype(np.float64)
    sym = 0.5 * (off + off[twin] * np.array([-1.0, 1.0, 1.0]))          # CMU's side axis is x
    return dataclasses.replace(windows, skeleton=dataclasses.replace(windows.skeleton, offsets=sym))


def test_mirrored_windows_are_the_mirror_image_of_their_positions():
    from inbetween_jax.data import load_dataset
    from inbetween_jax.geometry.mirror import MIRROR_TAG
    w = _symmetric(load_dataset(None, "train").take(slice(0, 12)))
    m = w.mirrored()
    twin = list(w.skeleton.mirror_map())
    ref = w.global_pose()[1][:, :, twin] * np.array([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(m.global_pose()[1], ref, atol=2e-3)            # cm, float32 windows
    np.testing.assert_array_equal(m.contacts, w.contacts[..., [2, 3, 0, 1]])   # left foot <-> right foot
    assert m.seq_names == [n + MIRROR_TAG for n in w.seq_names]
    assert np.all(np.sum(m.local_quats[:, 1:] * m.local_quats[:, :-1], -1) > 0)
    np.testing.assert_allclose(m.mirrored().local_quats, w.local_quats, atol=1e-6)
    np.testing.assert_allclose(m.mirrored().root_pos, w.root_pos, atol=1e-5)


def test_scvae_data_mirror_switch_adds_each_windows_mirror_image():
    from inbetween_jax.data import load_dataset
    from inbetween_jax.errors import UserError
    from inbetween_jax.geometry.mirror import MIRROR_TAG
    from inbetween_jax.models.scvae.bank import check_mirror
    from inbetween_jax.models.scvae.config import get_config
    from inbetween_jax.models.scvae.train import load_data
    from inbetween_jax.train.config import apply_overrides
    cfg = get_config("tiny")
    plain = load_data(cfg, "embedded")
    both = load_data(apply_overrides(cfg, ["data.mirror=true"]), "embedded")
    n = len(plain)
    assert len(both) == 2 * n and both.provenance["windows"] == 2 * n
    np.testing.assert_array_equal(both.q[:n], plain.q)
    mirrored = load_dataset("embedded", "train", window=cfg.data.window or None).mirrored()
    np.testing.assert_allclose(both.q[n:], mirrored.local_quats, atol=1e-6)
    np.testing.assert_allclose(both.r[n:], mirrored.root_pos, atol=1e-4)
    np.testing.assert_array_equal(both.c[n:], plain.c[..., [2, 3, 0, 1]])
    assert both.names[n] == plain.names[0] + MIRROR_TAG
    twin = np.asarray(plain.skeleton.mirror_map())
    lopsided = plain.skeleton.offsets.copy()
    lopsided[int(np.nonzero(twin != np.arange(len(twin)))[0][0])] *= 2.5      # one limb far longer
    with pytest.raises(UserError, match="clips: data.mirror: .*not left-right symmetric"):
        check_mirror(dataclasses.replace(plain.skeleton, offsets=lopsided), (0.0, 0.0, 1.0), "clips", "data.mirror")
