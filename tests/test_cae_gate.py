"""The CAE gate's floor-speed score (models/cae/gate.floor_scorer, models/ood.FloorSpeedScore): the speed it reads
from a gap's normalised context against the root's floor path of the same real CMU walk, its round trip through
``ood.npz``, and walking against standing."""
import numpy as np

from inbetween_jax.models.ood import FloorSpeedScore, Gate, load_gate, save_gate


def test_floor_speed_is_the_roots_floor_step_beside_the_gap(tmp_path, cae_fast_walk):
    from inbetween_jax.geometry import forward_kinematics
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.models.cae.gate import CONTEXT_FRAMES, floor_scorer, gap_context
    from inbetween_jax.models.cae.infer import load
    run, motion = cae_fast_walk                                # CMU 02_01: a walk at 1.2 m/s, 120 Hz
    model = load(run)
    x = model.normalizer(body_frame_features(motion).features).T[None].astype(np.float32)     # (1, D, T)
    scorer = floor_scorer(model.normalizer, model.num_joints, c=1.0)
    root = forward_kinematics(motion.local_quats, motion.local_pos, motion.skeleton.parents)[1][:, 0][:, [0, 2]]
    step = np.linalg.norm(np.diff(root, axis=0), axis=-1)      # frame t's step is root[t] - root[t - 1]
    for a, b in ((10, 30), (40, 70)):
        frames = [a + o if o < 0 else b + o for o in CONTEXT_FRAMES]
        expected = step[np.array(frames) - 1].mean()            # independent: global root path, no features
        ctx = gap_context(x, a, b)
        np.testing.assert_allclose(scorer.speed(ctx), [expected], rtol=1e-3)
        np.testing.assert_allclose(scorer.score(ctx), [1.0 / (1.0 + expected)], rtol=1e-3)
    assert expected > 1.0                                       # a walk: well above 1 data unit per frame
    save_gate(str(tmp_path), scorer, Gate(0.3, 0.6))
    back, gate = load_gate(str(tmp_path))
    assert isinstance(back, FloorSpeedScore) and (gate.lo, gate.hi) == (0.3, 0.6)
    np.testing.assert_allclose(back.score(ctx), scorer.score(ctx))


def test_standing_scores_higher_than_walking(cae_fast_walk):
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.models.cae.gate import floor_scorer, gap_context
    from inbetween_jax.models.cae.infer import load
    run, motion = cae_fast_walk
    model = load(run)
    feats = body_frame_features(motion).features
    still = np.repeat(feats[:1], len(feats), axis=0)            # the first pose held: no root motion
    still[:, 3 * model.num_joints:] = 0.0
    scorer = floor_scorer(model.normalizer, model.num_joints)
    walk_x, still_x = (model.normalizer(f).T[None].astype(np.float32) for f in (feats, still))
    walk, stand = scorer.score(gap_context(walk_x, 40, 70)), scorer.score(gap_context(still_x, 40, 70))
    np.testing.assert_allclose(stand, [1.0], atol=1e-4)
    assert walk[0] < 0.5
