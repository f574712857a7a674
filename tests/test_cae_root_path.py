"""The CAE's root path stays near its base path (model.root_bound): a fast walk at 120 Hz from the shared CMU
files, filled over 2 s through `inbetween infill`'s path (resampled to the run's rate)."""
import dataclasses

import numpy as np

from inbetween_jax.models.cae.features import bound_root_path, root_base_path


def test_bound_root_path_math():
    t = np.arange(20, dtype=np.float64)
    ref = np.stack([t, np.zeros(20)], 1)                       # a straight walk along x
    known = np.ones(20)
    known[5:15] = 0
    np.testing.assert_allclose(root_base_path(ref, known), ref, atol=1e-4)   # a line stays a line
    off = ref.copy()
    off[5:15, 1] = 30.0                                        # the fill swings 30 units sideways
    out = bound_root_path(off, known, 5.0)
    np.testing.assert_allclose(out[5:15, 1], 5.0, atol=1e-4)
    np.testing.assert_allclose(out[:5], off[:5])               # known frames untouched
    np.testing.assert_allclose(out[15:], off[15:])


def test_fast_walk_fill_root_stays_near_base_path(cae_fast_walk):
    from inbetween_jax.models.cae.infer import load, process_motion
    run, motion = cae_fast_walk                                # CMU 02_01: a walk at 1.2 m/s, 120 Hz, 43 joints
    model = load(run)
    bound = model.cfg.model.root_bound
    assert bound > 0, "the shipped CAE bounds its root path"
    t = motion.num_frames
    a, b = (t - 60) // 2, (t - 60) // 2 + 60                   # a 2-second gap in the middle
    known = np.ones(t)
    known[a:b] = 0

    def max_deviation(m):
        root = process_motion(m, motion, [(a, b)])["positions"][:, 0][:, [0, 2]]
        return np.linalg.norm(root - root_base_path(root, known), axis=-1)[a:b].max()
    assert max_deviation(model) <= bound * 100 + 1e-2          # metres -> the data's centimetres
    model.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, root_bound=0.0))
    assert max_deviation(model) > 2 * bound * 100              # unbounded, this fill swings away from it
