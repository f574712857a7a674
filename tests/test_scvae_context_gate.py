"""The S-CVAE's gate inside a clip (``model.context_gate``, :func:`inbetween_jax.models.scvae.gate.context_gate`):
read from ``ood.npz`` when it holds the thresholds, used only where the fill follows the frames beside the
keyframes, and calibrated against that fill's base (:func:`~inbetween_jax.models.scvae.calibrate.in_clip_records`)
on real CMU motion."""
import dataclasses
import os

import numpy as np
import pytest

from conftest import ROOT
from inbetween_jax.models.ood import BLEND_WEIGHTS, Gate

ASSETS = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30")


@pytest.fixture(scope="module")
def shipped():
    from inbetween_jax.data import read_bvh
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.shipped import shipped_run
    run = shipped_run("scvae")
    trained = infer.load(run)
    path = os.path.join(ASSETS, "13_10.bvh")
    return run, trained, prepare(read_bvh(path), path, trained.skeleton, run.fps).motion


def test_context_gate_is_read_only_when_ood_npz_holds_it(tmp_path):
    from inbetween_jax.models.ood import OOD_FILE
    from inbetween_jax.models.scvae.gate import CONTEXT_GATE_KEYS, context_gate
    assert context_gate(str(tmp_path)) is None                                  # no ood.npz at all
    np.savez(tmp_path / OOD_FILE, gate_lo=0.5, gate_hi=0.7)
    assert context_gate(str(tmp_path)) is None                                  # a gate calibrated before
    np.savez(tmp_path / OOD_FILE, gate_lo=0.5, gate_hi=0.7, **dict(zip(CONTEXT_GATE_KEYS, (0.1, 0.3))))
    g = context_gate(str(tmp_path))
    assert (g.lo, g.hi) == (0.1, 0.3)


def test_a_damaged_ood_npz_is_one_line_naming_the_file_for_both_optional_gates(tmp_path):
    """The in-clip thresholds and the CAE's k-NN cap are optional, but a file that is there and unreadable is
    an error naming it, not a traceback (nor silently no gate)."""
    from inbetween_jax.models.cae.gate import knn_cap
    from inbetween_jax.models.ood import OOD_FILE
    from inbetween_jax.models.scvae.gate import context_gate
    from inbetween_jax.train.run import RunError
    (tmp_path / OOD_FILE).write_bytes(b"PK\x03\x04 cut short")
    for load in (context_gate, knn_cap):
        with pytest.raises(RunError) as e:
            load(str(tmp_path))
        assert OOD_FILE in str(e.value) and "\n" not in str(e.value)


def _keys(m, k0, n, sides):
    k1 = k0 + n + 1
    s = {"q": m.local_quats[k0], "r": m.root_pos[k0], "c": np.zeros(4)}
    e = {"q": m.local_quats[k1], "r": m.root_pos[k1], "c": np.zeros(4)}
    if sides:
        s.update(qp=m.local_quats[k0 - 1], rp=m.root_pos[k0 - 1], qp2=m.local_quats[k0 - 2], rp2=m.root_pos[k0 - 2])
        e.update(qn=m.local_quats[k1 + 1], rn=m.root_pos[k1 + 1], qn2=m.local_quats[k1 + 2], rn2=m.root_pos[k1 + 2])
    return s, e


def test_the_clip_thresholds_apply_inside_a_clip_only(shipped):
    from inbetween_jax.models.scvae import infer
    _, trained, m = shipped
    fa = tuple(trained.extra["forward_axis"])
    shut, kept = Gate(-2.0, -1.0), Gate(2.0, 3.0)              # weight 0 / 1 whatever the score
    inside_shut = dataclasses.replace(trained, gate=(trained.gate[0], kept), context_gate=shut)
    all_shut = dataclasses.replace(trained, gate=(trained.gate[0], shut), context_gate=None)
    all_kept = dataclasses.replace(trained, gate=(trained.gate[0], kept), context_gate=None)
    s, e = _keys(m, 40, 20, sides=True)
    out = infer.infill_between(inside_shut, m.skeleton, s, e, 20, 1, 0, fa)
    assert out["context"] == "both sides" and out["gate_weight"] == 0.0
    np.testing.assert_allclose(out["r"], infer.infill_between(all_shut, m.skeleton, s, e, 20, 1, 0, fa)["r"])
    assert np.abs(out["r"] - infer.infill_between(all_kept, m.skeleton, s, e, 20, 1, 0, fa)["r"]).max() > 1e-3
    off = dataclasses.replace(inside_shut, cfg=dataclasses.replace(inside_shut.cfg, model=dataclasses.replace(
        inside_shut.cfg.model, context_gate=False)))                           # the switch off: the main gate
    assert infer.infill_between(off, m.skeleton, s, e, 20, 1, 0, fa)["gate_weight"] == 1.0
    many = infer.infill_between(inside_shut, m.skeleton, s, e, 20, 3, 0, fa)     # the sampled mode keeps the
    assert many["gate_weight"] == 0.0 and many["sample_gate_weight"] == 1.0     # two-keyframe gate's weight
    np.testing.assert_allclose(many["r"][0], out["r"][0], atol=1e-6)           # sample 0 is the fill
    assert np.abs(many["r"][1:] - many["r"][:1]).max() > 1e-3                   # the others still leave it
    s, e = _keys(m, 40, 20, sides=False)                                       # two keyframes alone: main gate
    bare = infer.infill_between(inside_shut, m.skeleton, s, e, 20, 1, 0, fa)
    assert bare["context"] == "none" and bare["gate_weight"] == 1.0


def test_in_clip_records_score_the_fill_against_the_hermite_path(shipped):
    """Weight 0 is the base itself (ratio 1); the base is the context fill, closer to the capture than Slerp on
    average; one record per gap of each length."""
    from inbetween_jax.models.scvae.calibrate import in_clip_records
    _, trained, m = shipped
    fa = tuple(trained.extra["forward_axis"])
    m = m.slice(0, 160)
    recs = in_clip_records(trained, [m], fa, lengths=(10, 30), stride=45)
    assert len(recs) == len(range(3, 160 - 10 - 2, 45)) + len(range(3, 160 - 30 - 2, 45))
    for r in recs:
        assert len(r["ratios_at"]) == len(BLEND_WEIGHTS) and r["ratios_at"][0] == pytest.approx(1.0)
        assert 0.0 < r["score"] <= 1.0
    assert np.mean([r["base_x_slerp"] for r in recs]) < 1.0
    assert len({round(r["ratios_at"][-1], 6) for r in recs}) > 1              # the learned fill differs per gap
