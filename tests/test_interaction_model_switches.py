"""Interaction model switches beyond the paper (keyframes inside the predicted frames, offsets to the keypose,
residual on a lerp, time to arrival, late adversarial term, full scheduled sampling) and the presets, on real
clips: the shipped CMU mocap paired as two characters (constructed pairs)."""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.models.interaction import data as idata
from inbetween_jax.models.interaction import batches as ibatches
from inbetween_jax.models.interaction import model as ia
from inbetween_jax.models.interaction.config import DEFAULT_PRESET, PRESETS, get_config
from inbetween_jax.models.interaction.infer import Trained, infill_features
from inbetween_jax.models.interaction.losses import adversarial_weight, generator_objective, \
    scheduled_sampling_prob
from inbetween_jax.models.interaction.train import BATCH_KEYS, training_batch
from inbetween_jax.train import apply_overrides

TINY = get_config("tiny")
TIMED = apply_overrides(TINY, ["model.residual=true", "model.tta=true", "model.key_offsets=true"])


def test_presets_switches_off_in_paper_and_cpu_on_in_improved():
    assert DEFAULT_PRESET == "improved"
    for name in ("paper", "cpu"):
        c = get_config(name)
        assert (c.data.key_inside, c.model.key_offsets, c.model.residual, c.model.tta) == (0.0, False, False, False)
        assert (c.loss.adv_start, c.loss.adv_ramp, c.data.ar_steps, c.data.ss_max) == (0, 0, 3, 0.5)
        assert c.loss.w_pos == 1.0
    imp, cpu = get_config("improved"), get_config("cpu")
    assert imp.data.key_inside > 0 and imp.model.key_offsets and imp.model.residual and imp.model.tta
    assert imp.data.ss_max == 1.0 and imp.data.ar_steps > cpu.data.ar_steps and imp.loss.adv_start > 0
    assert imp.model.pjd_frames == imp.data.ar_steps * imp.data.n_pred and imp.loss.w_pos > 1
    assert dataclasses.replace(imp.train, split="train", keep_checkpoints=cpu.train.keep_checkpoints,
                               lr_schedule="constant", lr_final=cpu.train.lr_final, warmup_steps=0,
                               batch_size=cpu.train.batch_size, num_steps=cpu.train.num_steps) == cpu.train
    # the same budget in samples seen
    assert imp.train.batch_size * imp.train.num_steps == cpu.train.batch_size * cpu.train.num_steps
    assert imp.train.lr_schedule == "cosine" and cpu.train.lr_schedule == "constant"    # chosen on validation
    assert imp.train.split == "fit" and not imp.model.refiner and cpu.model.refiner     # chosen on validation
    same = ("dct_coeffs", "conv_channels", "hidden", "gcn_layers", "latent", "refiner_hidden", "pae_hidden")
    assert all(getattr(imp.model, k) == getattr(cpu.model, k) for k in same)
    # augmentation measured without gain on the validation take: off everywhere (same data as the paper)
    assert all(get_config(n).data.tempo == () and not get_config(n).data.reverse for n in PRESETS)
    # one network per preset: an ensemble (model.members) is M times the training budget, opted into by override
    assert all(get_config(n).model.members == 1 for n in PRESETS)
    assert all(get_config(n).loss.w_speed == 0.0 for n in PRESETS)     # measured, not adopted (ninth round)


def test_default_batch_is_one_sample_batch_call(pair_train):
    """Switches off: the batch is exactly the paper's sampling (same random stream, same arrays)."""
    d = TINY.data
    got = training_batch(pair_train, np.random.default_rng(3), TINY)
    ref = ibatches.sample_batch(pair_train, np.random.default_rng(3), TINY.train.batch_size,
                             d.n_input + d.ar_steps * d.n_pred, (d.key_min, d.key_max), d.mirror, d.pos_scale)
    assert set(got) == set(BATCH_KEYS)
    for k in BATCH_KEYS:
        np.testing.assert_array_equal(got[k], ref[k])


def test_key_inside_holds_the_keypose_after_the_keyframe(pair_train):
    cfg = apply_overrides(TINY, ["data.key_inside=0.5", "train.batch_size=8"])
    T, N = cfg.data.n_input, cfg.data.ar_steps * cfg.data.n_pred
    b = training_batch(pair_train, np.random.default_rng(0), cfg)
    tta = b["tta"].astype(int)
    assert np.all(tta[:4] > N) and np.all((tta[4:] >= 2) & (tta[4:] <= N))       # 4 outside, 4 inside
    for i in range(4, 8):
        k = T + tta[i] - 1                                                         # keyframe index in x
        held = b["x"][i, :, k:]
        np.testing.assert_array_equal(held, np.broadcast_to(b["keypose"][i][:, None], held.shape))
        assert np.abs(b["x"][i, :, k - 1] - b["keypose"][i]).max() > 1e-3           # real motion before it
    # without key_inside but timed: every keyframe stays where the paper puts it (beyond the predicted frames)
    b = training_batch(pair_train, np.random.default_rng(0), TIMED)
    assert np.all(b["tta"] > N) and np.all(b["tta"] <= cfg.data.key_max - T + 1)


def _inputs(pair_windows, cfg, gap):
    J = pair_windows["x"].shape[3]
    params = ia.init_params(jax.random.key(0), cfg, J)
    w = jnp.asarray(pair_windows["x"][:, :, :20])
    tta = jnp.full((w.shape[0],), gap + 1.0)
    return params, w, tta


def test_residual_untrained_model_returns_the_lerp_exactly(pair_windows, pair_train):
    fa = pair_train[0].forward_axis.astype(np.float32)
    for cfg, tta_given in ((TIMED, True), (apply_overrides(TINY, ["model.residual=true"]), False)):
        params, w, tta = _inputs(pair_windows, cfg, 30)
        out = ia.generator_step(params["gen"], w, pair_windows["keypose"], pair_windows["rel_R"], pair_windows["rel_t"],
                                jax.random.key(1), cfg, fa, tta if tta_given else None)
        reach = tta if tta_given else jnp.full_like(tta, cfg.model.lerp_frames)
        lerp = ia.lerp_to_keypose(w[:, :, -1], jnp.asarray(pair_windows["keypose"]), reach, cfg.data.n_pred)
        np.testing.assert_array_equal(np.asarray(out["pred"]), np.asarray(lerp))
        np.testing.assert_array_equal(np.asarray(out["coarse"]), np.asarray(lerp))
        assert np.abs(np.asarray(lerp[:, :, -1] - w[:, :, -1])).max() > 1e-2    # it does move
    # the paper's head is not a lerp
    params, w, _ = _inputs(pair_windows, TINY, 30)
    out = ia.generator_step(params["gen"], w, pair_windows["keypose"], pair_windows["rel_R"], pair_windows["rel_t"],
                            jax.random.key(1), TINY, fa)
    lerp = ia.lerp_to_keypose(w[:, :, -1], jnp.asarray(pair_windows["keypose"]), jnp.full((w.shape[0],), 31.0), 10)
    assert not np.allclose(np.asarray(out["pred"]), np.asarray(lerp), atol=1e-3)


def test_untrained_timed_model_arrives_and_honours_the_gap(pair_windows, pair_train):
    """The stop rule fires for the residual / tta model within 2x the gap; the gap changes the motion."""
    fa = pair_train[0].forward_axis.astype(np.float32)
    params, w, _ = _inputs(pair_windows, TIMED, 30)
    kp, R, t = pair_windows["keypose"], pair_windows["rel_R"], pair_windows["rel_t"]
    run = jax.jit(lambda g: ia.rollout(params, w, kp, R, t, jax.random.key(2), TIMED, fa, 6, gap=g))
    frames, length = run(30)
    assert np.all(np.asarray(length) <= 30)                           # at the latest after the gap (2x allowed)
    full, _ = ia.rollout(params, w, kp, R, t, jax.random.key(2), TIMED, fa, 3, threshold=-1.0, gap=30)
    d = np.asarray(ia.keypose_distance(full[:, :, 29], kp)).max(1)
    assert np.all(d < 0.2 * TIMED.model.stop_threshold)               # 1/31 of the way left at frame 30
    late, length = run(50)
    assert np.all(np.asarray(length) <= 50)
    assert np.abs(np.asarray(late[:, :, 9] - frames[:, :, 9])).max() > 1e-2     # slower when given more time


def test_key_offsets_are_an_input(pair_windows, pair_train):
    fa = pair_train[0].forward_axis.astype(np.float32)
    cfg = apply_overrides(TINY, ["model.key_offsets=true"])
    params, w, _ = _inputs(pair_windows, cfg, 30)
    k = params["gen"]["enc"]["proj"]["kernel"]
    base = ia.init_params(jax.random.key(0), TINY, w.shape[3])["gen"]["enc"]["proj"]["kernel"]
    assert k.shape[0] == base.shape[0] + 9 and ia.extra_features(cfg) == 18
    kp, R, t = pair_windows["keypose"], pair_windows["rel_R"], pair_windows["rel_t"]
    step = lambda p: ia.generator_step(p["gen"], w, kp, R, t, jax.random.key(1), cfg, fa)["pred"]  # noqa: E731
    zeroed = jax.tree.map(lambda a: a, params)
    zeroed["gen"]["enc"]["proj"]["kernel"] = k.at[-9:].set(0.0)                  # the offset rows
    assert np.abs(np.asarray(step(params) - step(zeroed))).max() > 1e-6


def test_tta_input_changes_the_prediction_and_is_required(pair_windows, pair_train):
    fa = pair_train[0].forward_axis.astype(np.float32)
    cfg = apply_overrides(TINY, ["model.tta=true"])
    params, w, tta = _inputs(pair_windows, cfg, 30)
    args = (w, pair_windows["keypose"], pair_windows["rel_R"], pair_windows["rel_t"], jax.random.key(1), cfg, fa)
    a = ia.generator_step(params["gen"], *args, tta)["pred"]
    b = ia.generator_step(params["gen"], *args, tta - 25.0)["pred"]
    assert np.abs(np.asarray(a - b)).max() > 1e-6
    with pytest.raises(ValueError, match="tta"):
        ia.generator_step(params["gen"], *args)


def test_latent_scale_zero_is_deterministic(pair_windows, pair_train):
    """``model.latent_scale``: 1 samples z around the encoder's mean (different keys, different rollouts); 0 uses
    the mean (every key gives the same rollout)."""
    fa = jnp.asarray(pair_train[0].forward_axis, jnp.float32)
    params, w, _ = _inputs(pair_windows, TINY, 30)
    params["gen"]["film"] = jax.tree.map(lambda a: a + 0.3, params["gen"]["film"])  # z must reach the output
    out = {s: ia.sample_rollouts(params, w, pair_windows["keypose"], pair_windows["rel_R"], pair_windows["rel_t"],
                                 jax.random.key(2), TINY, fa, 2, 3, threshold=-1.0, latent_scale=s)[0]
           for s in (0.0, 1.0)}
    assert np.abs(np.asarray(out[1.0][0] - out[1.0][1])).max() > 1e-5
    np.testing.assert_allclose(np.asarray(out[0.0][0]), np.asarray(out[0.0][2]), atol=1e-6)


def test_adversarial_weight_warms_up_late(pair_train):
    np.testing.assert_allclose(float(adversarial_weight(jnp.float32(0.0), TINY)), TINY.loss.w_adv, rtol=1e-6)
    cfg = apply_overrides(TINY, ["loss.adv_start=100", "loss.adv_ramp=50", "data.ss_max=0.0"])
    w = [float(adversarial_weight(jnp.float32(s), cfg)) for s in (0, 99, 100, 125, 150, 1000)]
    np.testing.assert_allclose(w, np.array([0, 0, 0, 0.5, 1, 1]) * cfg.loss.w_adv, rtol=1e-6)
    off = apply_overrides(TINY, ["loss.adv_start=100", "data.ss_max=0.0"])
    np.testing.assert_allclose([float(adversarial_weight(jnp.float32(s), off)) for s in (99, 100)],
                               [0.0, off.loss.w_adv], rtol=1e-6)
    # in the objective: the total changes by exactly w_adv * adv between before and after the warm-up
    b = training_batch(pair_train, np.random.default_rng(1), cfg)
    params = ia.init_params(jax.random.key(0), cfg, b["x"].shape[3])
    fa = pair_train[0].forward_axis.astype(np.float32)
    (t0, (m0, _)), (t1, (m1, _)) = [generator_objective(params, dict(b, step=jnp.float32(s)), jax.random.key(0),
                                                        cfg, fa) for s in (0, 500)]
    assert float(m0["adv"]) > 0 and float(m0["w_adv"]) == 0.0
    np.testing.assert_allclose(float(t1 - t0), cfg.loss.w_adv * float(m1["adv"]), rtol=1e-3)


def test_full_scheduled_sampling_and_more_steps(pair_train):
    """ss_max = 1 ends in full feedback: the predictions no longer depend on the ground truth after the context."""
    cfg = apply_overrides(TINY, ["data.ar_steps=5", "model.pjd_frames=50", "data.ss_max=1.0",
                                 "data.key_min=71", "data.key_max=80"])
    assert float(scheduled_sampling_prob(jnp.float32(10 ** 6), cfg)) == 1.0
    b = training_batch(pair_train, np.random.default_rng(2), cfg)
    assert b["x"].shape[2] == 20 + 50
    params = ia.init_params(jax.random.key(0), cfg, b["x"].shape[3])
    fa = pair_train[0].forward_axis.astype(np.float32)
    run = lambda x, p: ia.ar_predict(params["gen"], dict(b, x=x), jax.random.key(4), cfg, fa, p)[0]  # noqa
    x2 = b["x"].copy()
    x2[:, :, 20:] += 0.5
    pred = run(b["x"], 1.0)
    assert pred.shape == (b["x"].shape[0], 2, 50) + b["x"].shape[3:]
    np.testing.assert_array_equal(np.asarray(pred), np.asarray(run(x2, 1.0)))
    assert not np.allclose(np.asarray(run(b["x"], 0.0)), np.asarray(run(x2, 0.0)))


def test_infill_honours_frames_with_tta(pair_windows, pair_train):
    """``--frames N``: an untrained residual / tta model is at the keypose after N frames, for two N."""
    fa = np.asarray(pair_train[0].forward_axis, np.float64)
    J = pair_windows["x"].shape[3]
    cfg = dataclasses.replace(TIMED, model=dataclasses.replace(TIMED.model, refiner=False))
    trained = Trained(cfg, ia.init_params(jax.random.key(0), cfg, J), J, fa, None, 0, "")
    pair = pair_train[3]
    context, key = pair.feats[:, 10:30].astype(np.float64), pair.feats[:, 60].astype(np.float64)
    for n in (12, 25):
        out = infill_features(trained, context, key, n, 1)
        assert out.shape == (1, 2, n, J, 9)
        gap_cm = np.linalg.norm(out[0, :, -1, :, :3] - key[..., :3], axis=-1).mean()
        step_cm = np.linalg.norm(out[0, :, -2, :, :3] - out[0, :, -1, :, :3], axis=-1).mean()
        assert gap_cm < 1.5 * step_cm, (n, gap_cm, step_cm)                      # one lerp step from the key


def test_residual_refiner_starts_as_identity(pair_windows):
    """With model.residual the refiner's output layer starts at zero (the untrained rollout is the lerp, refiner
    on); the paper's refiner is not the identity."""
    lerp_like = jnp.asarray(pair_windows["x"][:, :, 20:30])
    for cfg, identity in ((TIMED, True), (TINY, False)):
        params = ia.init_params(jax.random.key(0), cfg, lerp_like.shape[3])
        out = np.asarray(ia.refine(params["ref"], lerp_like, cfg))
        assert np.allclose(out, np.asarray(lerp_like), atol=1e-4) == identity


def test_bench_model_method_is_told_the_true_or_guessed_gap(pair_windows, pair_train):
    """The bench's model rows tell a timed model the window's own gap (30 here) even when the rollout is longer
    (the stop-rule rollout runs 2x the gap), or the guessed-length baseline's guess."""
    from inbetween_jax.evaluation.interaction import guess_gap_length
    from inbetween_jax.models.interaction.bench import _model_method
    fa = np.asarray(pair_train[0].forward_axis, np.float64)
    J = pair_windows["x"].shape[3]
    trained = Trained(TIMED, ia.init_params(jax.random.key(0), TIMED, J), J, fa, None, 0, "")
    kp = np.asarray(pair_windows["keypose"])
    long = _model_method(trained)(pair_windows, 6, 1, jax.random.key(0))[0]        # 60 frames for a 30-frame gap
    d = np.asarray(ia.keypose_distance(jnp.asarray(long[:, :, 30]), kp)).max(1)
    assert long.shape[2] == 60 and np.all(d < 1e-3)                           # frame 31 is the keyframe
    guess = guess_gap_length(pair_windows)
    assert np.any(guess != 30)
    guessed = _model_method(trained, gap="guess")(pair_windows, 6, 1, jax.random.key(0))[0]
    for i in np.flatnonzero(guess < 59):
        di = np.asarray(ia.keypose_distance(jnp.asarray(guessed[i:i + 1, :, guess[i]]), kp[i:i + 1])).max()
        assert di < 1e-3
    with pytest.raises(ValueError, match="gap"):
        _model_method(trained, gap="oracle")


def test_bench_guessed_gap_with_the_bank_follows_the_rollouts_own_arrival(pair_windows, pair_train):
    """With a guessed gap, ``model.bank_guessed`` applies the bank over the gap the network's own rollout takes
    (the frames before it meets the stop threshold, found on a rollout of ARRIVAL_HORIZON frames), not over the
    guess; frames after it are the network's and only the frames asked for come back.  Without the switch the
    guessed rows are the network alone."""
    from inbetween_jax.models.interaction.bank import MotionBank, arrival_gaps, knn_inbetween
    from inbetween_jax.models.interaction.bench import ARRIVAL_HORIZON, _model_method
    fa = np.asarray(pair_train[0].forward_axis, np.float64)
    J = pair_windows["x"].shape[3]
    bank = MotionBank.from_pairs(pair_train, TIMED.data.pos_scale, stride=3)
    only_bank = dataclasses.replace(TIMED.model, bank_k=1, bank_weight=1.0)
    params = ia.init_params(jax.random.key(0), TIMED, J)
    alone = Trained(TIMED, params, J, fa, None, 0, "")
    key, steps, long = jax.random.key(3), 3, ARRIVAL_HORIZON // TIMED.data.n_pred
    net = _model_method(alone, gap="guess")(pair_windows, long, 1, key)[0]           # (B, 2, 100, J, 9)
    off = Trained(dataclasses.replace(TIMED, model=only_bank), params, J, fa, None, 0, "", bank)
    np.testing.assert_array_equal(_model_method(off, gap="guess")(pair_windows, steps, 1, key)[0], net[:, :, :30])
    on = Trained(dataclasses.replace(TIMED, model=dataclasses.replace(only_bank, bank_guessed=True)), params, J, fa,
                 None, 0, "", bank)
    out = _model_method(on, gap="guess")(pair_windows, steps, 1, key)[0]
    assert out.shape == (len(net), 2, 30, J, 9)
    arrive = arrival_gaps(net, pair_windows["keypose"], TIMED.model.stop_threshold, TIMED.data.pos_scale)
    assert len(set(arrive.tolist())) > 1 and np.all(arrive <= bank.max_gap(20))
    ctx, kp = pair_windows["x"][:, :, :20], pair_windows["keypose"]
    for i, a in enumerate(arrive):
        n = min(int(a), 30)
        near = knn_inbetween(bank, ctx[i:i + 1], kp[i:i + 1], int(a), 1)[0]
        np.testing.assert_allclose(out[i, :, :n], near[:, :n], atol=1e-5)
        np.testing.assert_array_equal(out[i, :, n:], net[i, :, n:30])


def test_position_weight_in_the_mse():
    """loss.w_pos scales only the position channels' squared error; 1 is the plain MSE."""
    from inbetween_jax.models.interaction.losses import mse
    target = jnp.zeros((1, 2, 3, 4, 9))
    pos_err = target.at[..., 0].set(0.1)                       # 10 cm in x everywhere
    rot_err = target.at[..., 5].set(0.1)
    assert float(mse(pos_err, target)) == pytest.approx(0.01 / 9)
    assert float(mse(pos_err, target, 20.0)) == pytest.approx(20 * 0.01 / 9)
    assert float(mse(rot_err, target, 20.0)) == pytest.approx(float(mse(rot_err, target)))


def test_speed_energy_asks_for_motion_not_its_phase(pair_windows, pair_train):
    """The motion-energy term is 0 for the capture and for the capture mirrored through the last input frame (the
    same speeds, every frame wrong: a large MSE), has a finite gradient on held frames, equals a numpy re-derivation
    for the capture damped halfway towards that frame, and with loss.w_speed the generator objective grows by
    exactly w_speed times it."""
    from inbetween_jax.models.interaction.losses import mse, speed_energy
    x = np.asarray(pair_windows["x"][:, :, 19:30], np.float64)              # (B, 2, 11, J, 9) real frames
    prev, gt = x[:, :, :1], x[:, :, 1:]
    mirrored = gt.copy()
    mirrored[..., :3] = 2 * prev[..., :3] - gt[..., :3]
    j = lambda a: jnp.asarray(a, jnp.float32)  # noqa: E731
    assert float(speed_energy(j(gt), j(gt), j(prev))) == 0.0
    assert float(speed_energy(j(mirrored), j(gt), j(prev))) < 1e-8
    held = np.repeat(prev, gt.shape[2], 2)                                  # a held pose (the keypose after arrival)
    assert np.isfinite(np.asarray(jax.grad(speed_energy)(j(held), j(gt), j(prev)))).all()
    assert float(mse(j(mirrored), j(gt))) > 1e-3
    damped = prev + 0.5 * (gt - prev)

    def mean_speed(a):                                                      # (B, 2, J) metres per frame
        pos = np.concatenate([prev, a], 2)[..., :3]
        return np.mean([np.linalg.norm(pos[:, :, t + 1] - pos[:, :, t], axis=-1) for t in range(a.shape[2])], 0)
    want = np.mean(((mean_speed(damped) - mean_speed(gt)) / mean_speed(gt).mean()) ** 2)
    np.testing.assert_allclose(float(speed_energy(j(damped), j(gt), j(prev))), want, rtol=1e-3)
    assert want > 0.05
    cfg = apply_overrides(TINY, ["loss.w_speed=2.0", "data.ss_max=0.0"])
    b = training_batch(pair_train, np.random.default_rng(1), cfg)
    params = ia.init_params(jax.random.key(0), cfg, b["x"].shape[3])
    fa = pair_train[0].forward_axis.astype(np.float32)
    (t0, (m0, _)), (t1, (m1, _)) = [generator_objective(params, dict(b, step=jnp.float32(0)), jax.random.key(0),
                                                        c, fa) for c in (TINY, cfg)]
    assert "speed" not in m0 and float(m1["speed"]) > 0
    np.testing.assert_allclose(float(t1 - t0), 2.0 * float(m1["speed"]), rtol=1e-3)
