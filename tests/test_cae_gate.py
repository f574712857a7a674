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


def test_knn_cap_thresholds_are_the_validation_gaps_quantiles():
    from inbetween_jax.models.cae.gate import knn_cap_thresholds
    scores = np.arange(1, 101) / 100.0                         # pure math: 0.01 .. 1.00
    g = knn_cap_thresholds(scores)
    assert g.lo == np.quantile(scores, 0.9) and g.hi == 1.0
    assert g.weight(0.5) == 1.0 and g.weight(1.0) == 0.0 and 0.0 < g.weight(0.95) < 1.0


def test_knn_cap_takes_the_smaller_weight_and_is_read_from_the_shipped_gate(tmp_path, cae_fast_walk):
    """The shipped CAE's ood.npz holds the cap; a walk whose speed gate keeps the network keeps it under an open
    cap and loses it under a shut one (the gap becomes the pre-fill); a folder without the cap gives None."""
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.models.cae.gate import base_fill, gate_clips, knn_cap
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    run, motion = cae_fast_walk
    model = load(run)
    assert model.knn_cap is not None and knn_cap(str(tmp_path)) is None
    fm = gap_frames(motion.num_frames, [(40, 70)])
    x = model.normalizer(body_frame_features(motion, known=fm > 0.5).features).T[None].astype(np.float32)
    mask = frame_mask_image(fm, model.num_joints)[None]
    y = model.predict(x * mask, mask)
    base = base_fill(model, x * mask, mask)
    model.knn_cap = (model.knn_cap[0], Gate(1e6, 2e6))         # open whatever the score
    kept, info = gate_clips(model, x * mask, mask, np.asarray(y))
    assert info[0][0]["knn_weight"] == 1.0 and info[0][0]["gate_weight"] > 0.5      # a walk: the speed gate opens
    model.knn_cap = (model.knn_cap[0], Gate(-2.0, -1.0))       # shut whatever the score
    shut, info = gate_clips(model, x * mask, mask, np.asarray(y))
    assert info[0][0]["gate_weight"] == 0.0
    np.testing.assert_allclose(shut[0, :, 40:70], base[0, :, 40:70], atol=1e-6)
    assert np.abs(kept[0, :, 40:70] - base[0, :, 40:70]).max() > 1e-3


def test_shut_gap_takes_the_edge_faded_base_and_dropped_joints_the_pre_fill(cae_fast_walk):
    """The shipped CAE's base (model.base_edge_fade > 0): a shut gap's body rows are the limited Hermite with the
    cut edge tangents faded back in, its root rows the plain limited Hermite, and on real motion the base leaves
    the keyframe closer to the motion's own velocity than the limited fill; joint dropout keeps the pre-fill."""
    from inbetween_jax.baselines import hermite_fill
    from inbetween_jax.models.cae.features import body_frame_features
    from inbetween_jax.models.cae.gate import gate_clips
    from inbetween_jax.models.cae.infer import load
    from inbetween_jax.models.cae.masks import frame_mask_image, gap_frames
    run, motion = cae_fast_walk
    model = load(run)
    k, j = model.cfg.model.base_edge_fade, model.num_joints
    assert k > 0
    a, b = 20, 50
    fm = gap_frames(motion.num_frames, [(a, b)])
    x = model.normalizer(body_frame_features(motion, known=fm > 0.5).features).T[None].astype(np.float32)
    mask = frame_mask_image(fm, j)[None].copy()
    mask[0, 0:3, 60:70] = 0.0                                 # one joint dropped for ten frames
    model.knn_cap = (model.knn_cap[0], Gate(-2.0, -1.0))       # shut whatever the score
    y = np.asarray(model.predict(x * mask, mask))
    out, info = gate_clips(model, x * mask, mask, y)
    limited, faded = hermite_fill(x * mask, mask), hermite_fill(x * mask, mask, edge_fade=k)
    assert info[0][0]["gate_weight"] == 0.0
    np.testing.assert_allclose(out[0, :3 * j, a:b], faded[0, :3 * j, a:b], atol=1e-6)
    np.testing.assert_allclose(out[0, 3 * j:, a:b], limited[0, 3 * j:, a:b], atol=1e-6)
    np.testing.assert_allclose(out[0, 0:3, 60:70], limited[0, 0:3, 60:70], atol=1e-6)
    v = (3 * x[0, :3 * j, a - 1] - 4 * x[0, :3 * j, a - 2] + x[0, :3 * j, a - 3]) / 2   # velocity into the gap
    cut = v * (x[0, :3 * j, b] - x[0, :3 * j, a - 1]) < 0       # rows whose tangent the limiter zeroes
    assert cut.sum() >= 3
    miss_f = np.abs(out[0, :3 * j, a] - x[0, :3 * j, a - 1] - v)[cut]
    miss_l = np.abs(limited[0, :3 * j, a] - x[0, :3 * j, a - 1] - v)[cut]
    assert miss_f.mean() < 0.5 * miss_l.mean()
