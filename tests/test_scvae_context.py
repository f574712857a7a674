"""The S-CVAE's fill inside a clip (``model.context_base``, :mod:`inbetween_jax.models.scvae.context`): the
two-sided Hermite offsets (pure math on synthetic curves), and on real CMU motion with the shipped weights: the
keyframes stay exact, no context changes nothing, the fill leaves and reaches the keyframes with the motion's
own velocity, and it is closer to the capture than the Slerp-based fill."""
import dataclasses
import json
import os

import jax.numpy as jnp
import numpy as np
import pytest

from conftest import ROOT
from inbetween_jax.baselines.velocity_interpolation import end_hermite_weights, hermite_weights, velocity_offsets

ASSETS = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30")


def test_end_basis_is_zero_at_both_keyframes_and_has_unit_slope_at_the_end():
    L = 400
    g = np.asarray(end_hermite_weights(L, L + 5))
    f = np.asarray(hermite_weights(L, L + 5))
    assert g[0] == 0 and abs(g[L]) < 1e-9 and np.all(g[L:] == 0) and np.all(g[1:L] < 0)
    assert (g[L] - g[L - 1]) == pytest.approx(1.0, abs=3.0 / L)       # arrives with the end tangent
    assert (g[1] - g[0]) == pytest.approx(0.0, abs=3.0 / L)           # leaves with none of it
    assert (f[1] - f[0]) == pytest.approx(1.0, abs=3.0 / L) and (f[L] - f[L - 1]) == pytest.approx(0.0, abs=3.0 / L)


def test_two_sided_offsets_vanish_on_uniform_motion_and_bend_a_root_path_toward_both_velocities():
    """Constant velocity on both sides: the Hermite path is the lerp (offsets zero).  A root that arrives
    moving faster than the secant: the path's last step is larger than the lerp's, its first step unchanged."""
    B, J, L = 2, 3, 20
    q = jnp.tile(jnp.asarray([1.0, 0.0, 0.0, 0.0]), (B, J, 1))
    r0, r1 = jnp.zeros((B, 3)), jnp.tile(jnp.asarray([2.0, 0.0, 0.0]), (B, 1))
    step = (r1 - r0) / L
    dq, dr = velocity_offsets(q, q, q, r0 - step, r0, r1, L, L, q_next=q, r_next=r1 + step)
    np.testing.assert_allclose(np.asarray(dr), 0.0, atol=1e-6)
    np.testing.assert_allclose(np.abs(np.asarray(dq)[..., 0]), 1.0, atol=1e-6)
    _, dr = velocity_offsets(q, q, q, r0 - step, r0, r1, L, L, q_next=q, r_next=r1 + 3 * step)
    path = np.asarray(r0)[:, None] + np.linspace(0, 1, L + 1)[None, :, None] * np.asarray(r1 - r0)[:, None] + dr
    steps = np.diff(path[..., 0], axis=1)
    assert steps[0, -1] > 1.5 * float(step[0, 0]) and steps[0, 0] == pytest.approx(float(step[0, 0]), rel=0.2)
    np.testing.assert_allclose(path[:, [0, L]], np.stack([r0, r1], 1), atol=1e-6)


def _shipped_scvae():
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.shipped import shipped_run
    run = shipped_run("scvae")
    if run is None:
        pytest.skip("no S-CVAE weights ship in this tree")
    return run, infer.load(run)


def _switch(trained, **kw):
    return dataclasses.replace(trained, cfg=dataclasses.replace(trained.cfg, model=dataclasses.replace(
        trained.cfg.model, **kw)))


def test_shipped_fill_follows_the_motion_beside_the_keyframes_on_real_cmu_motion():
    from inbetween_jax.data import read_bvh
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.geometry import forward_kinematics
    from inbetween_jax.models.scvae import infer
    run, trained = _shipped_scvae()
    assert trained.cfg.model.context_base
    off = _switch(trained, context_base=False)
    fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
    path = os.path.join(ASSETS, "13_10.bvh")                     # a test subject: everyday motion, never trained on
    m = prepare(read_bvh(path), path, trained.skeleton, run.fps).motion
    lp = lambda r: np.concatenate([r[..., None, :], np.broadcast_to(m.local_pos[0, 1:], r.shape[:-1] + (  # noqa
        m.skeleton.num_joints - 1, 3))], -2)
    gp = forward_kinematics(m.local_quats, lp(m.root_pos), m.skeleton.parents)[1]
    n, errs = 20, {"context": [], "slerp": []}
    for k0 in range(5, m.num_frames - n - 3, 60):
        k1 = k0 + n + 1
        s = {"q": m.local_quats[k0], "r": m.root_pos[k0], "c": np.zeros(4)}
        e = {"q": m.local_quats[k1], "r": m.root_pos[k1], "c": np.zeros(4)}
        plain = infer.infill_between(off, m.skeleton, s, e, n, 1, 0, fa)
        bare = infer.infill_between(trained, m.skeleton, s, e, n, 1, 0, fa)   # no neighbours given: unchanged
        assert bare["context"] == "none" and plain["context"] == "none"
        np.testing.assert_allclose(bare["q"], plain["q"], atol=1e-6)
        s.update(qp=m.local_quats[k0 - 1], rp=m.root_pos[k0 - 1], qp2=m.local_quats[k0 - 2], rp2=m.root_pos[k0 - 2])
        e.update(qn=m.local_quats[k1 + 1], rn=m.root_pos[k1 + 1], qn2=m.local_quats[k1 + 2], rn2=m.root_pos[k1 + 2])
        out = infer.infill_between(trained, m.skeleton, s, e, n, 1, 0, fa)
        assert out["context"] == "both sides"
        np.testing.assert_allclose(out["q"][0, [0, -1]], m.local_quats[[k0, k1]], atol=1e-6)
        np.testing.assert_allclose(out["r"][0, [0, -1]], m.root_pos[[k0, k1]], atol=1e-6)
        if out["gate_weight"] == 0.0:        # the gate closed: the root follows the Hermite path, leaving at the
            v_in, v_out = m.root_pos[k0] - m.root_pos[k0 - 1], out["r"][0, 1] - out["r"][0, 0]   # motion's speed
            secant = (m.root_pos[k1] - m.root_pos[k0]) / (n + 1)
            assert np.linalg.norm(v_out - v_in) < np.linalg.norm(v_in - secant) + 1e-9
        for key, res in (("context", out), ("slerp", plain)):
            fill = forward_kinematics(res["q"][0, 1:-1], lp(res["r"][0, 1:-1]), m.skeleton.parents)[1]
            errs[key].append(np.linalg.norm(fill - gp[k0 + 1:k1], axis=-1).mean())
    assert len(errs["context"]) >= 4
    assert np.mean(errs["context"]) < 0.95 * np.mean(errs["slerp"])


def test_infill_json_says_which_neighbours_the_fill_followed(tmp_path):
    from inbetween_jax.cli import main
    _shipped_scvae()
    bvh = os.path.join(ASSETS, "13_10.bvh")
    for start, end, kind in ((40, 70, "both sides"), (0, 30, "after the end")):
        out = tmp_path / kind.replace(" ", "_")
        assert main(["infill", "--model", "scvae", "--start", f"{bvh}:{start}", "--end", f"{bvh}:{end}", "--frames",
                     str(end - start - 1), "--samples", "3", "--out", str(out)]) == 0
        info = json.load(open(out / "infill.json"))
        assert info["context"] == kind
        moved = [s["toward_captured"] for s in info["samples_ood"]]   # sample 0 is the fill; the others by the gate
        two_keyframe = info.get("sample_gate_weight", info["gate_weight"])    # inside a clip: that gate's weight
        assert moved[0] == 0.0 and moved[1] == moved[2] == pytest.approx(0.15 * two_keyframe, abs=1e-4)
        assert info["gate_weight"] <= two_keyframe + 1e-12                  # the in-clip thresholds are stricter


def test_neighbour_velocity_is_capped_and_small_motion_kept():
    from inbetween_jax.geometry import quat_conj, quat_from_axis_angle, quat_mul, quat_to_axis_angle
    from inbetween_jax.models.scvae.context import limit_neighbour
    axis = np.array([[0.0, 0.6, 0.8], [1.0, 0.0, 0.0]])
    key = quat_from_axis_angle(np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]), np.array([0.3, -1.0]))[None]
    nb = quat_mul(key, quat_from_axis_angle(axis, np.array([1.4, 0.1]))[None])      # a glitch, then real motion
    r_key, r_nb = np.zeros((1, 3)), np.array([[30.0, 0.0, 40.0]])
    q, r = limit_neighbour(key, r_key, nb, r_nb, 0.35, 10.0)
    ax, ang = quat_to_axis_angle(quat_mul(quat_conj(key), q))
    np.testing.assert_allclose(ang[0], [0.35, 0.1], atol=1e-9)
    np.testing.assert_allclose(ax[0], axis, atol=1e-9)
    np.testing.assert_allclose(r, [[6.0, 0.0, 8.0]], atol=1e-9)                    # 50 units -> 10, same direction
    q0, r0 = limit_neighbour(key, r_key, nb, r_nb, 0.0, 0.0)                         # 0: no cap
    np.testing.assert_allclose(np.abs(np.sum(q0 * nb, -1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(r0, r_nb)
    # two frames on the side: per joint the smaller of the one-frame step and half the two-frame step, so a
    # glitched nearest frame (joint 0) is outvoted by the frame beyond it and real motion (joint 1) is kept
    nb2 = quat_mul(key, quat_from_axis_angle(axis, np.array([0.1, 0.2]))[None])
    q2, r2 = limit_neighbour(key, r_key, nb, r_nb, 0.0, 0.0, nb2, np.array([[2.0, 0.0, 0.0]]))
    ax, ang = quat_to_axis_angle(quat_mul(quat_conj(key), q2))
    np.testing.assert_allclose(ang[0], [0.05, 0.1], atol=1e-9)
    np.testing.assert_allclose(r2, [[1.0, 0.0, 0.0]], atol=1e-12)


def test_a_side_needs_two_frames_and_the_bench_windows_give_them():
    from inbetween_jax.models.scvae.config import ModelConfig
    from inbetween_jax.models.scvae.context import context_kind, neighbours
    from inbetween_jax.data import load_dataset
    wins = load_dataset("embedded", "benchmark").take(slice(0, 2))
    q, r = wins.local_quats, wins.root_pos
    k0, k1 = 9, 40
    keys = (q[:, k0], r[:, k0], q[:, k1], r[:, k1])
    nb = neighbours(ModelConfig(), wins.skeleton, *keys, (q[:, k0 - 1], r[:, k0 - 1], q[:, k0 - 2], r[:, k0 - 2]),
                    (q[:, k1 + 1], r[:, k1 + 1], None, None))
    assert nb[0] is not None and nb[2] is None and nb[3] is None
    assert context_kind({"qp": 0, "rp": 0, "qp2": 0, "rp2": 0}, {"qn": 0, "rn": 0}) == "before the start"


def test_clip_keyframes_pass_the_sides_a_motion_holds_and_positions_of_is_its_forward_kinematics():
    """:func:`clip_keyframes` on a real CMU file: both sides inside the clip, none at its first frames or past
    its last, the keyframes' own frames and the given contacts; ``Motion.positions_of`` on the motion's own
    rotations is its per-frame forward kinematics (``global_positions``)."""
    from inbetween_jax.data import read_bvh
    from inbetween_jax.models.scvae.context import AFTER, BEFORE, clip_keyframes, context_kind
    m = read_bvh(os.path.join(ASSETS, "02_01.bvh"), 0, 60)
    s, e = clip_keyframes(m, 5, 26)
    assert context_kind(s, e) == "both sides"
    for got, want in ((s["q"], m.local_quats[5]), (s["qp2"], m.local_quats[3]), (e["r"], m.root_pos[26]),
                      (e["rn"], m.root_pos[27]), (e["qn2"], m.local_quats[28])):
        np.testing.assert_array_equal(got, want)
    assert np.all(s["c"] == 0) and np.all(e["c"] == 0)
    assert context_kind(*clip_keyframes(m, 1, 20)) == "after the end"
    assert context_kind(*clip_keyframes(m, 30, 58)) == "before the start"
    c0, c1 = np.array([1.0, 0, 0, 1]), np.array([0, 1.0, 1, 0])
    s, e = clip_keyframes(m, 0, 59, (c0, c1))
    assert not any(k in s for k in BEFORE) and not any(k in e for k in AFTER)
    assert s["c"] is c0 and e["c"] is c1
    np.testing.assert_allclose(m.positions_of(m.local_quats, m.root_pos), m.global_positions(), atol=1e-9)
    np.testing.assert_allclose(m.positions_of(m.local_quats[7], m.root_pos[7]), m.global_positions()[7], atol=1e-9)


def test_a_model_whose_base_continues_the_start_gets_the_end_side_only():
    """``model.base_velocity`` (``improved-velocity``): the network's own base already continues the frame before
    the start keyframe, so the fill inside a clip adds only the end side's motion (not the start's twice)."""
    from inbetween_jax.data import read_bvh
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.models.scvae import infer
    run, trained = _shipped_scvae()
    vel = _switch(trained, base_velocity=True, ood_gate=False)
    fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
    path = os.path.join(ASSETS, "13_10.bvh")
    m = prepare(read_bvh(path), path, trained.skeleton, run.fps).motion
    k0, k1, n = 60, 81, 20
    frame = lambda i: {"q": m.local_quats[i], "r": m.root_pos[i]}  # noqa: E731
    s = {**frame(k0), "c": np.zeros(4), "qp": m.local_quats[k0 - 1], "rp": m.root_pos[k0 - 1]}
    e = {**frame(k1), "c": np.zeros(4), "qn": m.local_quats[k1 + 1], "rn": m.root_pos[k1 + 1],
         "qn2": m.local_quats[k1 + 2], "rn2": m.root_pos[k1 + 2]}
    two = dict(s, qp2=m.local_quats[k0 - 2], rp2=m.root_pos[k0 - 2])
    a, b = (infer.infill_between(vel, m.skeleton, x, e, n, 1, 0, fa) for x in (two, s))
    np.testing.assert_allclose(a["r"], b["r"], atol=1e-9)             # the start side's frames are not used
    c = infer.infill_between(_switch(trained, ood_gate=False), m.skeleton, two, e, n, 1, 0, fa)
    assert np.abs(c["r"] - a["r"]).max() > 1e-3                        # without base_velocity they are


def test_the_one_sided_path_reads_no_frame_after_the_end():
    """``in_clip(use_after=False)`` (experiments/scvae_past_frames.py): moving the two frames after the end keyframe
    changes the two-sided path and not the one continuing the frames before the start, which still leaves Slerp."""
    from inbetween_jax.data import load_dataset
    from inbetween_jax.models.scvae.config import ModelConfig
    from inbetween_jax.models.scvae.context import in_clip
    from inbetween_jax.models.scvae.gate import slerp_base
    wins = load_dataset("embedded", "benchmark").take(slice(0, 4))
    moved = wins.local_quats.copy(), wins.root_pos.copy()
    moved[1][:, 41:43] += np.array([30.0, 0.0, -20.0])
    other = dataclasses.replace(wins, local_quats=moved[0], root_pos=moved[1])
    cfg = ModelConfig(context_damping=0.1)
    q = np.broadcast_to(wins.local_quats[None, :, 10:40], (1, 4, 30) + wins.local_quats.shape[2:])
    r = np.broadcast_to(wins.root_pos[None, :, 10:40], (1, 4, 30, 3))
    one, one_moved = (in_clip(w, 10, 30, q, r, cfg, use_after=False) for w in (wins, other))
    two, two_moved = (in_clip(w, 10, 30, q, r, cfg) for w in (wins, other))
    np.testing.assert_allclose(one[3], one_moved[3])
    np.testing.assert_allclose(one[1], one_moved[1])
    assert np.abs(two[3] - two_moved[3]).max() > 1.0
    sr = slerp_base(wins.local_quats[:, 9], wins.root_pos[:, 9], wins.local_quats[:, 40], wins.root_pos[:, 40], 30)[1]
    assert np.abs(one[3][0] - sr).max() > 0.1                                  # it does continue the start's motion
