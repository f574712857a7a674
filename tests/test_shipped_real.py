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
