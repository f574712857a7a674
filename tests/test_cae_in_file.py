"""The CAE inside a file (:mod:`inbetween_jax.models.cae.in_file`, the bench's ``"inside a file"`` rows) on a
validation subject's walk with the shipped weights: the base the ratio divides by is what ``infill`` itself gives
when its gate closes and nothing is matched (ratio 1 to the last digits), the limited Hermite fill is that base
without its edge fades, the matched walk gaps beat it, and the straight-line ratio is the error over straight lines between the joint positions beside the gap."""
from __future__ import annotations

import copy
import dataclasses
import os

import numpy as np
import pytest

from inbetween_jax.data import load_motions
from inbetween_jax.models.cae.in_file import gap_records
from inbetween_jax.models.ood import Gate


@pytest.fixture(scope="module")
def shipped_and_walk():
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.shipped import shipped_run
    walk = [m for m in load_motions("cmu", "val-subjects") if os.path.basename(str(m.source)) == "12_01.bvh"][0]
    return load(shipped_run("cae")), walk


def test_a_closed_gate_without_matching_is_the_base(shipped_and_walk):
    model, walk = shipped_and_walk
    closed = copy.copy(model)
    closed.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, match_k=0))
    closed.gate = (model.gate[0], Gate(-2.0, -1.0))                 # every score is above hi: weight 0
    recs = gap_records(closed, [walk], limit=2)
    assert len(recs) >= 3 and {r["frames"] for r in recs} == {30, 60}
    np.testing.assert_allclose([r["ratio"] for r in recs], 1.0, atol=1e-6)
    assert not any(r["matched"] for r in recs)
    # the base gives the limited Hermite's cut edge velocity back (model.base_edge_fade, root_edge_fade): on a walk
    # it is the better fill, and without those fades the base is the limited Hermite itself
    assert np.mean([r["x_limited"] for r in recs]) < 0.99
    unfaded = copy.copy(closed)
    unfaded.cfg = dataclasses.replace(closed.cfg, model=dataclasses.replace(closed.cfg.model, base_edge_fade=0.0,
                                                                              root_edge_fade=0.0))
    plain = gap_records(unfaded, [walk], limit=2)
    np.testing.assert_allclose([r["x_limited"] for r in plain], 1.0, atol=1e-6)
    np.testing.assert_allclose([r["ratio"] for r in plain], 1.0, atol=1e-6)


def test_matched_walk_gaps_beat_their_base(shipped_and_walk):
    model, walk = shipped_and_walk
    recs = gap_records(model, [walk], seconds=(1,), limit=3)
    assert len(recs) == 3 and all(r["matched"] for r in recs)
    assert np.mean([r["ratio"] for r in recs]) < 0.95
    assert all(0.0 < r["x_straight"] < 1.5 for r in recs)
