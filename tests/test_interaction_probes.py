"""The interaction probes' building blocks (:mod:`inbetween_jax.models.interaction.probes`), which the
experiments/interaction_*.py scripts and docs/results/interaction.md use: argument parsing, formatting, the
degraded ground-truth rows and the ensemble rollout.  Synthetic arrays (shapes of the bench's windows)."""
from __future__ import annotations

import numpy as np
import pytest

from inbetween_jax.errors import UserError
from inbetween_jax.evaluation.interaction import N_INPUT
from inbetween_jax.models.interaction import probes
from inbetween_jax.models.interaction.config import get_config


def test_run_and_step():
    assert probes.run_and_step("runs/pairs/r_adv@1500") == ("runs/pairs/r_adv", 1500)
    assert probes.run_and_step("runs/pairs/r_adv") == ("runs/pairs/r_adv", None)
    assert probes.run_and_step("odd@name") == ("odd@name", None)


def test_parse_try_types_the_switches_and_refuses_others():
    model = get_config().model
    out = probes.parse_try("model.bank_k=8,model.bank_weight=0.25,model.bank_guessed=true", model)
    assert (out.bank_k, out.bank_weight, out.bank_guessed) == (8, 0.25, True)
    assert type(out.bank_k) is int and type(out.bank_weight) is float
    for bad in ("model.lr=1", "model.bank_k"):
        with pytest.raises(UserError, match="not KEY=VALUE of a bank switch"):
            probes.parse_try(bad, model)


def test_formatting():
    assert probes.fmt([0.12345, 2]) == "0.123 / 2.000"
    assert probes.ratios([1.0, 3.0], [2.0, 4.0]) == "0.5000 / 0.7500"


def test_truth_variants_on_synthetic_windows():
    rng = np.random.default_rng(0)
    B, J, L = 3, 4, 12
    x = rng.normal(size=(B, 2, N_INPUT + L + 1, J, 9)).astype(np.float32)
    rows = probes.truth_variants()
    b = {"x": x}
    np.testing.assert_array_equal(rows["ground truth"](b, L), x[:, :, N_INPUT:N_INPUT + L])
    hold = rows["hold last frame"](b, L)
    assert hold.shape == (B, 2, L, J, 9) and np.all(hold == x[:, :, N_INPUT - 1:N_INPUT])
    smooth = rows["ground truth smoothed, sigma 2 frames"](b, L)
    assert smooth.shape == (B, 2, L, J, 9)
    assert np.abs(np.diff(smooth, axis=2)).mean() < np.abs(np.diff(x[:, :, N_INPUT:N_INPUT + L], axis=2)).mean()


def test_mean_rollout_averages_the_methods():
    import jax

    def constant(v):
        return lambda b, steps, samples, key: np.full((samples, 2, 2, steps * 10, 1, 9), v, np.float32)

    out = probes.mean_rollout([constant(1.0), constant(3.0)])({}, 2, 1, jax.random.key(0))
    assert out.shape == (1, 2, 2, 20, 1, 9) and np.all(out == 2.0)
    made = probes.rollout(constant(5.0))({}, 13)                  # ceil(13 / 10) steps, cut to 13 frames
    assert made.shape == (2, 2, 13, 1, 9)
