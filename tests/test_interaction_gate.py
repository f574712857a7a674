"""The interaction model's out-of-distribution gate (models/interaction/gate.py, calibrate.py): the speed score
against a direct re-derivation, the blend toward per-character interpolation, calibration on the validation take,
and the shipped gate on real capture (salsa training takes against CMU motion of an activity it never saw)."""
import json
import os

import numpy as np
import pytest

from inbetween_jax.models.interaction.gate import gate_blend, interpolation_base, window_context
from inbetween_jax.models.ood import Gate, SpeedScore, load_gate, save_gate

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAIRS = os.path.join(os.path.dirname(ROOT), "shared", "data", "cmu_pairs")
needs_pairs = pytest.mark.skipif(not os.path.isdir(PAIRS), reason="shared salsa pairs not beside the repository")


def _windows(source, split=None, length=30):
    from inbetween_jax.models.interaction.batches import eval_windows
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    pairs = load_pairs(source, 150.0)
    return eval_windows(split_pairs(pairs, split, (0.85, 0.05, 0.1)) if split else pairs, 20, length, 10, 0.01)


@needs_pairs
def test_speed_context_is_the_mean_joint_speed_of_both_dancers():
    b = _windows(PAIRS, "fit")
    ctx = b["x"][:, :, :20]
    got = window_context(ctx)[:, 0]
    i = 7                                                   # one window, joint by joint
    want = np.mean([np.sqrt(np.sum((ctx[i, c, 19, j, :3] - ctx[i, c, 18, j, :3]) ** 2)) * 100
                    for c in range(2) for j in range(ctx.shape[3])])
    assert got.shape == (len(ctx),) and abs(got[i] - want) < 1e-4
    assert 0.5 < np.median(got) < 20.0                      # cm per frame of dancing at 30 fps
    s = SpeedScore(c=2.0).score(window_context(ctx))
    np.testing.assert_allclose(s, 1.0 / (1.0 + got / 2.0), rtol=1e-6)


@needs_pairs
def test_gate_blend_keeps_the_rollout_at_one_and_gives_interpolation_at_zero():
    b = _windows(PAIRS, "val")
    ctx, kp = b["x"][:4, :, :20], b["keypose"][:4]
    truth = np.asarray(b["x"][:4, :, 20:50])[None]                 # real frames standing in for a rollout
    rollouts = np.concatenate([truth, truth[:, :, :, -5:]], 3)      # 5 frames past the gap: left alone
    base = interpolation_base(ctx, kp, 30)
    out = gate_blend(rollouts, base, np.array([1.0, 0.0, 0.5, 0.0]))
    np.testing.assert_allclose(out[0, 0], rollouts[0, 0], atol=1e-5)
    np.testing.assert_allclose(out[0, 1, :, :30], base[1], atol=1e-5)
    np.testing.assert_allclose(out[0, :, :, 30:], rollouts[0, :, :, 30:])
    mid = 0.5 * (rollouts[0, 2, :, :30, :, :3] + base[2, :, :, :, :3])
    np.testing.assert_allclose(out[0, 2, :, :30, :, :3], mid, atol=1e-5)
    for lo in (3, 6):                                               # forward / up stay unit vectors
        np.testing.assert_allclose(np.linalg.norm(out[0, 2, ..., lo:lo + 3], axis=-1), 1.0, atol=1e-5)
    lin = np.asarray(ctx[:, :, -1, :, :3])[:, :, None] + (np.asarray(kp[:, :, :, :3]) - np.asarray(
        ctx[:, :, -1, :, :3]))[:, :, None] * (np.arange(1, 31) / 31.0)[None, None, :, None, None]
    np.testing.assert_allclose(base[..., :3], lin, atol=1e-4)       # positions: the straight line to the key


def test_speed_score_round_trips_through_ood_npz(tmp_path):
    save_gate(str(tmp_path), SpeedScore(1.5), Gate(0.3, 0.5))
    scorer, gate = load_gate(str(tmp_path))
    assert isinstance(scorer, SpeedScore) and scorer.c == 1.5 and (gate.lo, gate.hi) == (0.3, 0.5)
    np.testing.assert_allclose(gate.weight(scorer.score(np.array([[0.0], [1.5], [10.0]]))), [0.0, 0.0, 1.0])


@needs_pairs
def test_calibration_scores_the_validation_take_at_each_blend_weight():
    """At blend weight 0 the fill is interpolation (easing onto the key leaves a straight line as it is), so its
    ratio is 1; the gate chosen meets the limits it reports."""
    from inbetween_jax.models.interaction.calibrate import calibrate
    from inbetween_jax.shipped import shipped_run
    run = shipped_run("interaction")
    if run is None:
        pytest.skip("no interaction weights ship in this tree")
    res = calibrate(run, PAIRS, lengths=(30,), max_windows=8)
    at = np.array([r["ratios_at"] for r in res["records"]])
    assert at.shape == (8, 5) and all(r["name"].startswith("60+61_11@") for r in res["records"])   # take 11
    np.testing.assert_allclose(at[:, 0], 1.0, atol=1e-3)
    s = res["summary"]
    assert isinstance(res["bank"], SpeedScore) and s["windows"] == 8
    assert (not s["meets_limits"]) or (s["p90"] <= 1.05 + 1e-9 and s["max"] <= 1.5 + 1e-9)
    cap = run.config["model"]["departure_cap"]                  # the departure cap's part of each weight
    assert s["departure_cap"] == cap > 0 and res["arrays"]["base_error_coef"].shape == (4,)
    dep, capped = (np.array([r[k] for r in res["records"]]) for k in ("departure", "cap_weight"))
    np.testing.assert_allclose(capped, np.minimum(1.0, cap / dep), rtol=1e-9)


@needs_pairs
def test_shipped_gate_scores_an_unseen_activity_higher_than_the_training_takes():
    """CMU subject 14's everyday motion, two clips paired by us (an activity the salsa model never saw, on the same
    21-joint rig) scores higher than the salsa training takes, and the gate keeps less of the network there."""
    from inbetween_jax.shipped import shipped_dir
    folder = shipped_dir("interaction")
    if folder is None or load_gate(folder) is None:
        pytest.skip("no gated interaction weights ship")
    scorer, gate = load_gate(folder)
    assert json.load(open(os.path.join(folder, "run.json")))["config"]["model"]["ood_gate"]
    train = scorer.score(window_context(_windows(PAIRS, "fit")["x"][:, :, :20]))
    from inbetween_jax.models.interaction.batches import eval_windows
    from inbetween_jax.models.interaction.data import load_pairs
    everyday = [p for p in load_pairs("embedded", 150.0) if p.name == "14_07+14_08"]
    unseen = scorer.score(window_context(eval_windows(everyday, 20, 30, 10, 0.01)["x"][:, :, :20]))
    assert len(unseen) > 20 and np.median(unseen) > 1.5 * np.median(train)
    assert np.mean(gate.weight(unseen)) < 0.75 < 0.9 < np.mean(gate.weight(train))


@needs_pairs
def test_base_error_fit_matches_the_normal_equations_and_grows_with_the_gap():
    """The log-linear fit of interpolation's error (gate.fit_base_error) on the fit takes' windows equals the
    normal equations' solution, and on real salsa a longer gap and faster dancers mean a larger error."""
    from inbetween_jax.models.interaction.gate import base_error_features, fit_base_error
    from inbetween_jax.models.interaction.samples import window_errors_cm
    X, err = [], []
    for L in (30, 50):
        b = _windows(PAIRS, "fit", L)
        ctx = b["x"][:, :, :20]
        X.append(base_error_features(ctx, b["keypose"], L))
        err.append(window_errors_cm(interpolation_base(ctx, b["keypose"], L), b))
    X, err = np.concatenate(X), np.concatenate(err)
    coef = fit_base_error(X, err)
    np.testing.assert_allclose(coef, np.linalg.solve(X.T @ X, X.T @ np.log(err)), rtol=1e-6, atol=1e-8)
    assert coef[1] > 0.3 and coef[2] > 0.1                  # log gap, log joint speed
    resid = np.log(err) - X @ coef
    assert 1 - resid.var() / np.log(err).var() > 0.25       # R^2: the context says a good part of it


@needs_pairs
def test_departure_cap_bounds_how_far_the_fill_leaves_interpolation():
    """With the speed gate wide open, gate_rollouts with a cap c moves every window whose fill departs more than
    c times its predicted interpolation error back onto that bound (positions, sample 0) and leaves the others
    exactly as they were; every sample of a window gets the same weight."""
    from inbetween_jax.models.interaction.gate import (base_error_features, departure_cm, fit_base_error,
                                                       gate_rollouts, predicted_base_error_cm)
    from inbetween_jax.models.interaction.samples import window_errors_cm
    fit = _windows(PAIRS, "fit", 30)
    ctx = fit["x"][:, :, :20]
    coef = fit_base_error(base_error_features(ctx, fit["keypose"], 30),
                          window_errors_cm(interpolation_base(ctx, fit["keypose"], 30), fit))
    b = _windows(PAIRS, "val", 30)
    ctx, kp = b["x"][:12, :, :20], b["keypose"][:12]
    truth = np.asarray(b["x"][:12, :, 20:50])                       # real frames standing in for a rollout
    rollouts = np.stack([truth, truth[::-1]])                       # sample 1: other windows' frames
    base = interpolation_base(ctx, kp, 30)
    predicted, away = predicted_base_error_cm(coef, ctx, kp, 30), departure_cm(truth, base)
    cap = float(np.median(away / predicted))                        # half the windows over the bound
    parts = {}
    open_gate = (SpeedScore(), Gate(0.0, 1.0, enabled=False))
    out, _, weight = gate_rollouts(open_gate, rollouts, ctx, kp, np.full(12, 30), cap=cap, coef=coef, parts=parts)
    after = departure_cm(out[0], base)
    over = away > cap * predicted
    assert 3 <= over.sum() <= 9
    np.testing.assert_allclose(after[over], cap * predicted[over], rtol=1e-4)
    np.testing.assert_allclose(out[:, ~over], rollouts[:, ~over], atol=1e-6)
    np.testing.assert_allclose(weight, parts["departure_weight"])
    np.testing.assert_allclose(weight[over], cap * predicted[over] / away[over], rtol=1e-6)
    mid = base[over, ..., :3] + weight[over][:, None, None, None, None] * (rollouts[1, over, ..., :3] - base[over, ..., :3])
    np.testing.assert_allclose(out[1, over, ..., :3], mid, atol=1e-5)
    with pytest.raises(ValueError, match="coefficients"):
        gate_rollouts(open_gate, rollouts, ctx, kp, np.full(12, 30), cap=cap)
    only_fill, _, w0 = gate_rollouts(open_gate, rollouts, ctx, kp, np.full(12, 30), cap=cap, coef=coef,
                                     samples=False)               # model.bank_sample_gated=false
    np.testing.assert_array_equal(only_fill[0], out[0])
    np.testing.assert_array_equal(w0, weight)
    np.testing.assert_array_equal(only_fill[1], rollouts[1])
