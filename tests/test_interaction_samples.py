"""The interaction samples table (models/interaction/samples.py) on real salsa windows: per-window L2P against the
protocol's pooled L2P, and the table's columns on methods whose answers are known (interpolation: ten equal
samples; ground truth: zero error, ground truth's own score)."""
import os

import numpy as np
import pytest

from inbetween_jax.evaluation import interaction as proto
from inbetween_jax.models.interaction.samples import bench_rows, sample_table, window_l2p

PAIRS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "shared", "data",
                     "cmu_pairs")
pytestmark = pytest.mark.skipif(not os.path.isdir(PAIRS), reason="shared salsa pairs not beside the repository")


@pytest.fixture(scope="module")
def setting():
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    pairs = load_pairs(PAIRS, 150.0)
    train, val = split_pairs(pairs, "fit"), split_pairs(pairs, "val")
    windows = proto.table1_windows(val, 0.01, 6, (30,))
    cls = proto.train_classifier(train, train[0].feats.shape[2], (), steps=20)
    return windows, proto.l2p_stats(train, 0.01), cls[:2]


def test_window_l2p_averages_to_the_protocols_l2p(setting):
    windows, stats, _ = setting
    b = windows[30]
    pred = proto.interpolation_method(b, 3, 1, None)[0][:, :, :30]
    per = window_l2p(pred, b, stats)
    assert per.shape == (6,) and np.all(per > 0)
    np.testing.assert_allclose(per.mean(), proto.pair_l2p(pred, b, stats), rtol=1e-5)


def test_sample_table_on_known_methods(setting):
    windows, stats, cls = setting
    interp = sample_table(proto.interpolation_method, windows, stats, cls, num=4)[0]
    assert interp["frames"] == 30 and interp["windows"] == 6
    np.testing.assert_allclose([interp["mean_l2p"], interp["best_l2p"]], interp["interp_l2p"], rtol=1e-5)
    assert interp["apd_m"] < 1e-6 and interp["pairwise_cm"] < 1e-4      # ten copies of one answer
    truth = sample_table(proto.ground_truth_method, windows, stats, cls, num=2)[0]
    assert truth["mean_l2p"] < 1e-4 and truth["best_l2p"] < 1e-4
    np.testing.assert_allclose(truth["score"], truth["score_gt"], rtol=1e-5)
    flat, md = bench_rows([interp], "cmu_pairs", "Interpolation")
    cells = {r["metric"]: r["value"] for r in flat}
    assert all(r["table"] == "samples" and r["frames"] == 30 and r["model"] == "interaction" for r in flat)
    assert cells["best-of-N / interp"] == pytest.approx(1.0, rel=1e-5) and cells["apd_m"] < 1e-6
    assert "| 30 | 6 | 1.000 | 1.000 |" in md
