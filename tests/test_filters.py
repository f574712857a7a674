"""Temporal filters against scipy's."""
from __future__ import annotations

import numpy as np
import pytest

from inbetween_jax.data import load_motions
from inbetween_jax.data.filters import gaussian_lowpass


@pytest.mark.parametrize("sigma", [1.5, 2.5, 4.0])
def test_gaussian_lowpass_matches_scipy(sigma):
    """Real joint positions along time (axis 0 and a middle axis): scipy's gaussian_filter1d with edge
    repetition and the same 3-sigma truncation; the dtype asked for."""
    ndimage = pytest.importorskip("scipy.ndimage")
    pos = load_motions("embedded", "test")[0].global_positions()[:90]          # (T, J, 3)
    want = ndimage.gaussian_filter1d(np.asarray(pos, np.float64), sigma, axis=0, mode="nearest", truncate=3.0)
    got = gaussian_lowpass(pos, sigma, 0, np.float64)
    assert got.dtype == np.float64 and np.abs(got - want).max() < 1e-9
    moved = gaussian_lowpass(np.moveaxis(pos, 0, 1), sigma, 1)
    assert moved.dtype == np.float32
    np.testing.assert_allclose(np.moveaxis(moved, 1, 0), want, atol=1e-3)
    assert np.abs(got - pos).max() > 0.1                                        # it does smooth real motion
