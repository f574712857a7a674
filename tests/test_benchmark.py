"""The benchmark path (data -> baselines -> metrics) against the independent re-derivation of the
official LaFAN1 benchmark, and the S-CVAE Table 1 layout on real windows."""
import os

import numpy as np
import pytest

from inbetween_jax.data import load_dataset, read_bvh, windows_from_motions
from inbetween_jax.data import lafan1
from inbetween_jax.evaluation import (TABLE_COLUMNS, baseline_table1, markdown_table, official_baseline_table,
                                      transition_metrics)
from inbetween_jax.baselines import interpolate_transition

import lafan1_reference as ref
from conftest import LAFAN1_DIR, SHARED_DATA, requires_lafan1

FILES = ["ground1_subject5.bvh"]


@pytest.fixture(scope="module")
def official_stats():
    z = np.load(os.path.join(SHARED_DATA, "lafan1_stats", "official_l2p_train_stats.npz"))
    return z["x_mean"], z["x_std"]


@requires_lafan1
def test_official_baseline_numbers_match_independent_pipeline(official_stats):
    x_mean, x_std = official_stats
    paths = [os.path.join(LAFAN1_DIR, f) for f in FILES]
    rx, rq, parents = ref.windows(paths, 65, 40)
    ours = windows_from_motions([read_bvh(p) for p in paths], 65, 40, 10, lafan1.ROOT_FORWARD_AXIS)
    rows = official_baseline_table(ours, x_mean, x_std)
    names = {"Zero-velocity": "zerov", "Slerp": "interp"}
    for row in rows:
        expected = ref.benchmark(rx, rq, parents, x_mean, x_std, row["frames"])[names[row["method"]]]
        for k in ("L2Q", "L2P", "NPSS"):
            assert row[k] == pytest.approx(expected[k], rel=2e-3, abs=2e-5), (row, expected)
    # sanity: interpolation beats zero-velocity, errors grow with the gap
    by = {(r["method"], r["frames"]): r for r in rows}
    for n in (5, 15, 30, 45):
        assert by[("Slerp", n)]["L2P"] < by[("Zero-velocity", n)]["L2P"]
    assert by[("Slerp", 5)]["L2Q"] < by[("Slerp", 15)]["L2Q"] < by[("Slerp", 45)]["L2Q"]


def test_table1_layout_on_embedded_windows():
    bench = load_dataset("embedded", "benchmark")
    train = load_dataset("embedded", "train")
    from inbetween_jax.data import l2p_stats
    _, gp = train.global_pose()
    x_mean, x_std = l2p_stats(gp)
    rows = baseline_table1(bench, x_mean, x_std, lengths=(10, 30))
    assert [(r["method"], r["frames"]) for r in rows] == [("Zero-velocity", 10), ("Slerp", 10),
                                                          ("Zero-velocity", 30), ("Slerp", 30)]
    for r in rows:
        assert set(TABLE_COLUMNS) <= set(r) and all(np.isfinite(r[c]) for c in TABLE_COLUMNS)
        assert r["APD"] == 0.0
    # the ground truth scores zero error, and several identical samples have zero diversity
    gt_q = bench.local_quats[:, 10:40]
    gt_r = bench.root_pos[:, 10:40]
    perfect = transition_metrics(bench, 10, 30, np.stack([gt_q] * 3), np.stack([gt_r] * 3), x_mean, x_std)
    assert perfect["L2P"] < 1e-4 and perfect["L2Q"] < 1e-4 and perfect["ADE"] < 1e-5 and perfect["APD"] < 1e-6
    # two different "samples" (slerp, and slerp shifted 10 cm in x) have APD = the shift's norm in metres
    q, r = interpolate_transition(bench.local_quats, bench.root_pos, 10, 30)
    shifted = r + np.array([10.0, 0.0, 0.0], np.float32)
    two = transition_metrics(bench, 10, 30, np.stack([q, q]), np.stack([r, shifted]), x_mean, x_std)
    assert two["APD"] == pytest.approx(0.1 * np.sqrt(30 * bench.skeleton.num_joints), rel=1e-4)
    md = markdown_table(rows, TABLE_COLUMNS)
    assert md.count("\n") == len(rows) + 1 and "Slerp" in md


def test_impossible_lengths_and_nan_are_refused():
    bench = load_dataset("embedded", "benchmark")
    with pytest.raises(ValueError, match="needs windows longer"):
        official_baseline_table(bench, 0.0, 1.0, lengths=(60,))
    q = bench.local_quats[:, 10:15].copy()
    q[0, 0, 0, 0] = np.nan
    with pytest.raises(FloatingPointError, match="NaN"):
        transition_metrics(bench, 10, 5, q, bench.root_pos[:, 10:15], 0.0, 1.0)
