"""Datasets: LaFAN1 splits and windows against an independent re-derivation, the embedded default, caching."""
import os

import numpy as np
import pytest

from inbetween_jax.data import load_dataset, read_bvh, windows_from_motions
from inbetween_jax.data import lafan1
from inbetween_jax.data.datasets import EMBEDDED_DIR, split_files
from inbetween_jax.data.features import foot_contacts, l2p_stats
from inbetween_jax.geometry import quat_rotate

import lafan1_reference as ref
from conftest import LAFAN1_DIR, SHARED_DATA, requires_lafan1

TEST_FILE = "obstacles1_subject5.bvh"


@pytest.fixture(scope="module")
def ref_windows():
    return ref.windows([os.path.join(LAFAN1_DIR, TEST_FILE)], 65, 40)


@pytest.fixture(scope="module")
def lib_windows():
    motion = read_bvh(os.path.join(LAFAN1_DIR, TEST_FILE))
    return windows_from_motions([motion], 65, 40, 10, lafan1.ROOT_FORWARD_AXIS)


@requires_lafan1
def test_benchmark_windows_match_independent_pipeline(ref_windows, lib_windows):
    rx, rq, parents = ref_windows
    assert tuple(parents) == lib_windows.parents
    assert lib_windows.local_quats.shape == rq.shape == (len(lib_windows), 65, 22, 4)
    np.testing.assert_allclose(lib_windows.root_pos, rx[:, :, 0], atol=2e-3)  # float32 storage, cm
    dots = np.abs(np.sum(lib_windows.local_quats * rq, axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-5)


@requires_lafan1
def test_canonical_frame(lib_windows):
    root = lib_windows.root_pos.astype(np.float64)
    np.testing.assert_allclose(root[:, :, [0, 2]].mean(axis=1), 0.0, atol=1e-3)  # centred in XZ
    gq, _ = lib_windows.global_pose()
    fwd = quat_rotate(gq[:, 9, 0].astype(np.float64), np.array([0.0, 1.0, 0.0]))
    fwd[:, 1] = 0
    fwd /= np.linalg.norm(fwd, axis=-1, keepdims=True)
    np.testing.assert_allclose(fwd, np.tile([1.0, 0, 0], (len(fwd), 1)), atol=1e-4)  # faces +X at frame 9


@requires_lafan1
def test_split_sizes_match_the_data_readme():
    """The shared README states 5,465 training windows (50 @ 20) and 376 benchmark windows (65 @ 40)."""
    train = load_dataset(LAFAN1_DIR, "train")
    bench = load_dataset(LAFAN1_DIR, "benchmark")
    assert len(train) == 5465 and train.window == 50
    assert len(bench) == 376 and bench.window == 65
    assert all("subject5" in f for f in split_files(LAFAN1_DIR, "benchmark"))
    assert not any("subject5" in f for f in split_files(LAFAN1_DIR, "train"))
    # contacts are binary and present about a third of the time on LaFAN1 feet
    assert set(np.unique(train.contacts)) <= {0.0, 1.0} and 0.15 < train.contacts.mean() < 0.6
    # our own training statistics against the official ones (from all of subjects 1-4; we hold 24 files)
    stats = np.load(os.path.join(SHARED_DATA, "lafan1_stats", "official_l2p_train_stats.npz"))
    np.testing.assert_allclose(stats["offsets"][0, 0], train.skeleton.offsets[1:], atol=1e-4)
    _, gp = train.global_pose()
    x_mean, x_std = l2p_stats(gp)
    assert x_mean.shape == stats["x_mean"].shape == (1, 66, 1)
    ratio = x_std / stats["x_std"]
    assert 0.7 < ratio.min() and ratio.max() < 1.4  # 24 of the 62 training files: close, not equal


def test_embedded_default_is_real_and_split():
    train = load_dataset("embedded", "train")
    bench = load_dataset("embedded", "benchmark")
    assert train.skeleton.num_joints == 21 and train.window == 50 and bench.window == 65
    assert len(train) > 50 and len(bench) > 20
    names_train = {n.split("@")[0] for n in train.seq_names}
    names_bench = {n.split("@")[0] for n in bench.seq_names}
    assert not names_train & names_bench
    assert len(os.listdir(EMBEDDED_DIR)) >= 50
    # real motion: the hips stay between 60 and 120 cm above the floor on average, and move
    assert 60 < train.root_pos[..., 1].mean() < 120
    assert np.abs(np.diff(train.root_pos, axis=1)).max() > 1.0


def test_keyframe_pairs_give_the_frames_between_two_keyframes():
    """On a real embedded clip: each pair's truth is the clip's own FK positions strictly between its keyframes,
    every 40 frames; a gap longer than the clip is skipped."""
    from inbetween_jax.data.windows import keyframe_pairs
    from inbetween_jax.geometry import forward_kinematics
    m = read_bvh(os.path.join(EMBEDDED_DIR, sorted(f for f in os.listdir(EMBEDDED_DIR) if f.endswith(".bvh"))[0]))
    pos = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
    pairs = list(keyframe_pairs(m, lengths=(10, 30, m.num_frames)))
    assert [n for n, *_ in pairs] == [10, 30]
    for n, k0, k1, truth in pairs:
        assert k0[0] == 0 and np.all(np.diff(k0) == 40) and np.all(k1 - k0 == n + 1) and k1[-1] < m.num_frames
        assert truth.shape == (len(k0), n, m.skeleton.num_joints, 3)
        np.testing.assert_array_equal(truth[-1], pos[k0[-1] + 1:k1[-1]])


def test_cache_roundtrip_and_reversal(tmp_path, monkeypatch):
    monkeypatch.setenv("INBETWEEN_JAX_CACHE", str(tmp_path))
    a = load_dataset("embedded", "test")
    assert list((tmp_path / "windows").iterdir())
    b = load_dataset("embedded", "test")
    np.testing.assert_array_equal(a.local_quats, b.local_quats)
    assert a.skeleton.names == b.skeleton.names and a.seq_names == b.seq_names
    r = a.reversed()
    np.testing.assert_array_equal(r.root_pos[:, 0], a.root_pos[:, -1])
    np.testing.assert_array_equal(r.reversed().local_quats, a.local_quats)


def test_foot_contacts_threshold():
    feet = np.zeros((5, 1, 3))
    feet[:, 0, 0] = [0.0, 0.1, 0.2, 1.0, 1.0]  # squared steps 0.01, 0.01, 0.64, 0
    np.testing.assert_array_equal(foot_contacts(feet, 0.02)[:, 0], [1, 1, 0, 1, 1])


def test_missing_and_wrong_sources(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_dataset(str(tmp_path / "nowhere"), "train")
    with pytest.raises(FileNotFoundError, match="no .bvh files"):
        load_dataset(str(tmp_path), "train")
    with pytest.raises(ValueError, match="unknown split"):
        load_dataset("embedded", "validation")
