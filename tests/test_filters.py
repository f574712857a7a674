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


def test_gaussian_lowpass_over_known_frames_only():
    """With ``known``: scipy's normalised convolution (filtered x * m over filtered m) where a known frame lies within
    3 sigma; nothing read from the unknown frames (their values changed, the result is the same); all known is
    the plain filter; a frame with no known frame in reach takes its nearest such frame's result."""
    ndimage = pytest.importorskip("scipy.ndimage")
    pos = np.asarray(load_motions("embedded", "test")[0].global_positions()[:120, :4], np.float64)   # (T, 4, 3)
    known = np.ones(120, bool)
    known[40:75] = False                                      # a 35-frame gap: frames 52-62 out of reach
    known[:2] = False                                                         # and the first two frames
    m = known.astype(np.float64)[:, None, None]
    with np.errstate(invalid="ignore"):                                      # 0 / 0 out of reach
        ref = (ndimage.gaussian_filter1d(pos * m, 4.0, axis=0, mode="nearest", truncate=3.0)
               / ndimage.gaussian_filter1d(np.broadcast_to(m, pos.shape), 4.0, axis=0, mode="nearest", truncate=3.0))
    got = gaussian_lowpass(pos, 4.0, 0, np.float64, known=known)
    reach = np.convolve(known, np.ones(25), "same") > 0                      # a known frame within 12 frames
    assert reach.sum() < 120 and np.abs(got[reach] - ref[reach]).max() < 1e-9
    assert not reach[52:63].any() and reach[51] and reach[63]
    assert np.array_equal(got[52], got[51]) and np.array_equal(got[62], got[63])   # the nearest frames in reach
    scrambled = pos.copy()
    scrambled[~known] = pos[::-1][~known] + 100.0
    np.testing.assert_array_equal(gaussian_lowpass(scrambled, 4.0, 0, np.float64, known=known), got)
    np.testing.assert_allclose(gaussian_lowpass(pos, 4.0, 0, np.float64, known=np.ones(120, bool)),
                               gaussian_lowpass(pos, 4.0, 0, np.float64), atol=1e-9)
    with pytest.raises(ValueError):
        gaussian_lowpass(pos, 4.0, 0, known=np.zeros(120, bool))
