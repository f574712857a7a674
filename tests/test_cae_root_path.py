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


def test_edge_faded_root_path_leaves_the_keyframe_at_the_paths_speed():
    """A path that is still moving away when the gap starts and comes back across it (a turn): the limiter zeroes
    that edge tangent, so the limited Hermite stops the root dead at the keyframe; with ``edge_fade`` the root moves on
    at the path's speed, faded, and is the limited path again mid-gap, and ``bound_root_path`` holds a fill to it."""
    t = np.arange(60, dtype=np.float64)
    ref = np.stack([10.0 * np.sin(t / 12.0), 0.5 * t], 1)      # x turns back at t ~ 19
    known = np.ones(60)
    known[15:45] = 0
    limited, faded = root_base_path(ref, known), root_base_path(ref, known, edge_fade=0.4)
    step = ref[14, 0] - ref[13, 0]                              # still moving +x, the chord goes -x
    assert step > 0.3 and ref[45, 0] < ref[14, 0]
    assert abs(limited[15, 0] - ref[14, 0]) < 0.2 * step        # stopped dead
    assert faded[15, 0] - ref[14, 0] > 0.4 * step              # still moving on (exp(-0.4) of the cut speed)
    np.testing.assert_allclose(faded[28:32], limited[28:32], atol=0.05)
    np.testing.assert_allclose(faded[known > 0], ref[known > 0])
    off = faded.copy()
    off[15:45, 1] += 30.0
    np.testing.assert_allclose(bound_root_path(off, known, 5.0, edge_fade=0.4)[15:45, 1], faded[15:45, 1] + 5.0,
                               atol=1e-4)


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
        return np.linalg.norm(root - root_base_path(root, known, m.cfg.model.root_edge_fade), axis=-1)[a:b].max()
    assert max_deviation(model) <= bound * 100 + 1e-2          # metres -> the data's centimetres
    model.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, root_bound=0.0))
    assert max_deviation(model) > 2 * bound * 100              # unbounded, this fill swings away from it
