"""The samples overlay (inbetween_jax/viz_samples.py): one picture of N samples of the same frames, drawn from
real CMU motion; samples that differ fan out, identical ones draw one figure."""
import numpy as np
import pytest

from inbetween_jax.data import load_dataset
from inbetween_jax.viz_samples import samples_sheet


@pytest.fixture(scope="module")
def motion():
    w = load_dataset(None, "train").take(slice(0, 1))
    _, pos = w.global_pose()
    return np.asarray(pos[0, :30], np.float64), w.parents


def _coloured_pixels(path):
    import matplotlib.image as mpimg
    img = mpimg.imread(path)[..., :3]
    return int(np.sum(np.ptp(img, axis=-1) > 0.2))          # neither white, grey nor black


def test_samples_that_differ_fan_out_and_identical_samples_draw_one_figure(motion, tmp_path):
    pos, parents = motion
    same = np.stack([pos] * 4)
    spread = same.copy()
    spread[:, 1:-1] += np.arange(4)[:, None, None, None] * np.array([0.0, 8.0, 0.0])   # each sample 8 cm higher
    a = samples_sheet(same, parents, tmp_path / "same.png", every=5, keyframes=[0, 29])
    b = samples_sheet(spread, parents, tmp_path / "spread.png", every=5, keyframes=[0, 29])
    assert _coloured_pixels(b) > 2.0 * _coloured_pixels(a) > 0


def test_bad_samples_raise_one_line_and_write_nothing(motion, tmp_path):
    pos, parents = motion
    out = tmp_path / "x.png"
    for bad in (pos, np.stack([pos] * 21)):
        with pytest.raises(ValueError, match="samples must be"):
            samples_sheet(bad, parents, out)
    nan = np.stack([pos] * 2)
    nan[1, 3, 2, 0] = np.nan
    with pytest.raises(ValueError):
        samples_sheet(nan, parents, out)
    assert not out.exists()
