"""``data.tta_guess``: a time-to-arrival model also trained on the guessed gap (the evaluation's distance / speed
guess), told by a 4th input feature whether its time to arrival is the true one or a guess; on real clips (the
shipped CMU mocap paired as two characters)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.evaluation.interaction import guess_gap_length
from inbetween_jax.models.interaction import model as ia
from inbetween_jax.models.interaction.config import get_config
from inbetween_jax.models.interaction.train import load_data, make_training, training_batch
from inbetween_jax.train import apply_overrides

TINY = get_config("tiny")
# no residual: the tiny generator's output depends on its inputs from initialisation on
FLAGGED = apply_overrides(TINY, ["model.tta=true", "data.tta_guess=0.5", "data.key_inside=0.5"])


def test_model_guess_is_the_evaluation_guess(pair_windows):
    """The jax guess a flagged model makes for itself equals the guessed-length baseline's numpy guess."""
    ref = guess_gap_length(pair_windows)
    got = ia.speed_guess_gap(jnp.asarray(pair_windows["x"][:, :, :20]), jnp.asarray(pair_windows["keypose"]))
    assert np.array_equal(np.asarray(got).astype(int), ref)
    assert len(set(ref.tolist())) > 1                              # the pair_windows do not all guess alike


def test_batch_tells_the_guess_to_a_fraction_and_keeps_the_frames(pair_train):
    """Same draws as without the switch (frames, keyposes, true times); where ``tta_known`` is 0 the time to
    arrival is the guess + 1, elsewhere the truth; both occur."""
    flagged = apply_overrides(FLAGGED, ["train.batch_size=32"])
    plain = apply_overrides(flagged, ["data.tta_guess=0.0"])
    b = training_batch(pair_train, np.random.default_rng(3), flagged)
    ref = training_batch(pair_train, np.random.default_rng(3), plain)
    assert "tta_known" not in ref
    for k in ("x", "keypose", "rel_R", "rel_t"):
        np.testing.assert_array_equal(b[k], ref[k])
    known = b["tta_known"].astype(bool)
    assert 0 < known.sum() < len(known)
    np.testing.assert_array_equal(b["tta"][known], ref["tta"][known])
    guess = guess_gap_length({"x": ref["x"][:, :, :20], "keypose": ref["keypose"]})
    np.testing.assert_array_equal(b["tta"][~known], guess[~known] + 1)


def test_flag_is_an_input_and_rollouts_pass_it(pair_windows, pair_train):
    """The flag is a 4th time-to-arrival feature; telling the model a gap is guessed changes its rollout,
    and a rollout without a gap (stop rule on) is told its own guess as a guess.  Unflagged models ignore it."""
    fa = np.asarray(pair_train[0].forward_axis, np.float32)
    w, kp = jnp.asarray(pair_windows["x"][:, :, :20]), jnp.asarray(pair_windows["keypose"])
    R, t = jnp.asarray(pair_windows["rel_R"]), jnp.asarray(pair_windows["rel_t"])
    J = w.shape[3]
    assert ia.extra_features(FLAGGED) == 9 + ia.TTA_FEATURES + 1
    go = lambda cfg, **kw: np.asarray(ia.rollout(ia.init_params(jax.random.key(0), cfg, J), w, kp, R, t,  # noqa
                                                 jax.random.key(1), cfg, fa, 3, latent_scale=0.0, **kw)[0])
    told_true = go(FLAGGED, threshold=-1.0, gap=30)
    told_guess = go(FLAGGED, threshold=-1.0, gap=30, gap_known=False)
    assert np.abs(told_true - told_guess).max() > 1e-4
    own = go(FLAGGED, threshold=1e-6)                                           # never stops, guesses its gap
    guess = ia.speed_guess_gap(w, kp)
    np.testing.assert_allclose(own, go(FLAGGED, threshold=1e-6, gap=guess, gap_known=False), atol=1e-6)
    plain = apply_overrides(FLAGGED, ["data.tta_guess=0.0"])
    np.testing.assert_allclose(go(plain, threshold=-1.0, gap=30),
                               go(plain, threshold=-1.0, gap=30, gap_known=False), atol=0)


def test_guess_needs_the_time_input():
    cfg = apply_overrides(TINY, ["data.tta_guess=0.5"])
    with pytest.raises(ValueError, match="tta_guess needs model.tta"):
        make_training(cfg, load_data(cfg, "embedded"))
