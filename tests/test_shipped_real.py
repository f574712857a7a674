"""The weights that ship in the package: they load, and ``inbetween infill`` without ``--ckpt`` runs them on a raw
120 Hz, 43-joint CMU BVH file (joints matched by name, resampled to 30 Hz), writing finite motion on the file's
own skeleton that starts and ends on the keyframes."""
import json
import os

import numpy as np
import pytest

from conftest import ROOT

SHARED = os.path.join(os.path.dirname(ROOT), "shared", "data")
RAW = os.path.join(SHARED, "cmu_bvh", "02_01.bvh")


def _shipped_or_skip(model):
    from inbetween_jax.shipped import shipped_run
    run = shipped_run(model)
    if run is None:
        pytest.skip(f"no {model} weights ship in this tree")
    return run


@pytest.mark.parametrize("model", ["scvae", "cae"])
def test_shipped_weights_load_and_record_their_training(model):
    run = _shipped_or_skip(model)
    assert run.shipped["step"] == run.step and run.shipped.get("data_source")
    assert run.skeleton and run.fps == pytest.approx(30.0)


@pytest.mark.skipif(not os.path.exists(RAW), reason="shared CMU data not beside the repository")
def test_infill_without_ckpt_on_a_raw_cmu_file(tmp_path):
    from inbetween_jax.cli import main
    from inbetween_jax.data import read_bvh
    _shipped_or_skip("scvae")
    out = tmp_path / "out"
    assert main(["infill", "--model", "scvae", "--start", f"{RAW}:40", "--end", f"{RAW}:160", "--frames", "29",
                 "--samples", "2", "--out", str(out)]) == 0
    rec = json.load(open(out / "infill.json"))
    assert rec["weights"] == "shipped"
    src = read_bvh(RAW)
    names = sorted(f for f in os.listdir(out) if f.endswith(".bvh"))
    assert len(names) == 2
    m = read_bvh(str(out / names[0]))
    assert m.skeleton.names == src.skeleton.names                    # the user's full 43-joint skeleton
    assert np.isfinite(m.local_quats).all() and np.isfinite(m.root_pos).all()
    # 120 frames at 120 Hz = 1 s = 30 frames at the weights' 30 Hz, keyframes included at both ends
    assert m.num_frames == 31
    np.testing.assert_allclose(m.root_pos[0], src.root_pos[40], atol=0.5)
    np.testing.assert_allclose(m.root_pos[-1], src.root_pos[160], atol=0.5)


PAIR_A = os.path.join(SHARED, "cmu_pairs", "60_12_scaled.bvh")
PAIR_B = os.path.join(SHARED, "cmu_pairs", "61_12_scaled.bvh")


@pytest.mark.skipif(not os.path.exists(PAIR_A), reason="shared salsa pairs not beside the repository")
def test_interaction_infill_without_ckpt_on_the_dancers_files_as_given(tmp_path):
    """The salsa takes as captured (120 Hz, 43 joints, 1/128 units): one BVH per dancer on the input rig and
    unit, and one picture holding both dancers."""
    from inbetween_jax.cli import main
    from inbetween_jax.data import read_bvh
    from inbetween_jax.shipped import shipped_dir
    _shipped_or_skip("interaction")
    out = tmp_path / "out"
    assert main(["infill", "--model", "interaction", "--a", f"{PAIR_A}:400", "--b", f"{PAIR_B}:400",
                 "--key-a", f"{PAIR_A}:600", "--key-b", f"{PAIR_B}:600", "--frames", "49", "--samples", "2",
                 "--out", str(out), "--preview"]) == 0
    assert (out / "sample_00_pair_sheet.png").exists()
    info = json.load(open(out / "infill.json"))            # the out-of-distribution gate, per window and sample
    if os.path.exists(os.path.join(shipped_dir("interaction"), "ood.npz")):
        assert info["ood_score"] > 0 and 0.0 <= info["gate_weight"] <= info["departure_weight"] <= 1.0
        assert info["samples_ood"][0] == {"ood_score": info["ood_score"], "gate_weight": info["gate_weight"],
                                          "departure_weight": info["departure_weight"], "sample": "sample_00"}
        run = json.load(open(os.path.join(shipped_dir("interaction"), "run.json")))
        if not run["config"]["model"].get("bank_sample_gated", True):  # sample 1 is left as the bank made it
            assert info["samples_ood"][1] == {"ood_score": info["ood_score"], "gate_weight": 1.0,
                                              "departure_weight": 1.0, "sample": "sample_01"}
    for path, name in ((PAIR_A, "sample_00_A.bvh"), (PAIR_B, "sample_00_B.bvh")):
        src, m = read_bvh(path), read_bvh(str(out / name))
        assert m.skeleton.names == src.skeleton.names and m.num_frames == 51
        assert np.isfinite(m.local_quats).all() and np.isfinite(m.root_pos).all()
        # in the file's own unit (1 unit ~ 1.28 m): the root stays near the captured hip height
        assert 0.4 < float(np.median(m.root_pos[:, 1])) < 0.9
        np.testing.assert_allclose(m.root_pos[0], src.root_pos[400], atol=1e-3)
        np.testing.assert_allclose(m.root_pos[-1], src.root_pos[600], atol=1e-3)


@pytest.mark.skipif(not os.path.exists(PAIR_A), reason="shared salsa pairs not beside the repository")
def test_interaction_samples_differ_and_infill_json_says_by_how_much(tmp_path):
    """The sampled mode of the shipped weights: sample 0 is the deterministic fill, the others each blend in
    another captured window, so they differ by centimetres, not millimetres (``samples_pairwise_cm``)."""
    from inbetween_jax.cli import main
    from inbetween_jax.data import read_bvh
    _shipped_or_skip("interaction")
    runs = {}
    for n in (1, 3):
        out = tmp_path / f"out{n}"
        assert main(["infill", "--model", "interaction", "--a", f"{PAIR_A}:400", "--b", f"{PAIR_B}:400",
                     "--key-a", f"{PAIR_A}:600", "--key-b", f"{PAIR_B}:600", "--frames", "40", "--samples", str(n),
                     "--out", str(out)]) == 0
        runs[n] = out
    info = json.load(open(runs[3] / "infill.json"))
    assert info["samples_pairwise_cm"] > 2.0 and len(info["samples_spread_cm"]) == 3
    one, first = (read_bvh(str(runs[n] / "sample_00_A.bvh")) for n in (1, 3))
    np.testing.assert_allclose(first.root_pos, one.root_pos, atol=1e-4)          # sample 0: the deterministic fill
    other = read_bvh(str(runs[3] / "sample_01_A.bvh"))
    assert np.abs(other.root_pos - first.root_pos).max() > 0.01                  # 1/128-unit file: > 1.3 cm
