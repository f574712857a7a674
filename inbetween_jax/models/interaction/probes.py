"""Building blocks of the interaction probes (``experiments/interaction_*.py``, quoted in docs/results/interaction.md):
what the interaction score responds to, bank switches on the validation take, L2P on every test window.

A *make* is ``make(b, L) -> (B, 2, L, J, 9)``: the L in-between frames of the windows ``b`` in key space (after
the last context frame), the form :func:`score_windows` scores.  A *method* is the bench's
``method(b, steps, samples, key) -> (samples, B, 2, frames, J, 9)`` (``bench._model_method``).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from inbetween_jax.errors import UserError
from inbetween_jax.evaluation import interaction as proto
from inbetween_jax.evaluation.interaction import N_INPUT

__all__ = ["run_and_step", "parse_try", "fmt", "ratios", "rollout", "truth_variants", "score_windows",
           "classifier_scorer", "mean_rollout"]


def run_and_step(arg: str):
    """``RUN_DIR@STEP`` -> (RUN_DIR, STEP); ``RUN_DIR`` -> (RUN_DIR, None): the validation-selected step."""
    head, sep, tail = arg.rpartition("@")
    return (head, int(tail)) if sep and tail.isdigit() else (arg, None)


def parse_try(text: str, model_cfg):
    """``"model.bank_k=8,model.texture_gain=1.5"`` -> ``model_cfg`` with those bank switches replaced (typed as
    theirs); UserError (one line) for anything but ``KEY=VALUE`` of :data:`~.bank.SWITCHES`."""
    from inbetween_jax.models.interaction.bank import SWITCHES
    changes = {}
    for item in filter(None, text.split(",")):
        key, sep, value = item.partition("=")
        if not sep or key not in SWITCHES:
            raise UserError(f"--try {item}: not KEY=VALUE of a bank switch (choose {', '.join(SWITCHES)})")
        field = key.split(".", 1)[1]
        kind = type(getattr(model_cfg, field))
        changes[field] = value.lower() in ("1", "true", "yes") if kind is bool else kind(value)
    return dataclasses.replace(model_cfg, **changes)


def fmt(values, digits: int = 3) -> str:
    """``[0.1234, 0.5]`` -> ``"0.123 / 0.500"``."""
    return " / ".join(f"{x:.{digits}f}" for x in values)


def ratios(values, reference, digits: int = 4) -> str:
    """Element-wise ``values / reference``, formatted as :func:`fmt`."""
    return fmt([a / b for a, b in zip(values, reference)], digits)


def rollout(method, n_pred: int = 10):
    """The make of a bench method: one sample, ``ceil(L / n_pred)`` steps, the key ``key(L)``."""
    import jax
    return lambda b, L: method(b, -(-L // n_pred), 1, jax.random.key(L))[0][:, :, :L]


def truth_variants() -> dict:
    """{row name: make}: ground truth, ground truth low-pass filtered in time (Gaussian of 1, 2, 4 frames), blended
    with interpolation (0.75, 0.5), interpolation with the true gap, holding the last frame."""
    from inbetween_jax.models.interaction.bank import gaussian_lowpass

    def gt(b, L):
        return b["x"][:, :, N_INPUT:N_INPUT + L]

    def smoothed(sigma):
        return lambda b, L: gaussian_lowpass(b["x"][:, :, :N_INPUT + L + 1], sigma, 2)[:, :, N_INPUT:N_INPUT + L]

    def interp(b, L):
        return proto.interpolation_method(b, -(-L // 10), 1, None)[0][:, :, :L]

    def blend(w):
        return lambda b, L: w * gt(b, L) + (1 - w) * interp(b, L)

    def hold(b, L):
        return np.repeat(b["x"][:, :, N_INPUT - 1:N_INPUT], L, 2)

    return {"ground truth": gt, "ground truth smoothed, sigma 1 frame": smoothed(1.0),
            "ground truth smoothed, sigma 2 frames": smoothed(2.0),
            "ground truth smoothed, sigma 4 frames": smoothed(4.0),
            "0.75 ground truth + 0.25 interpolation": blend(0.75), "0.5 ground truth + 0.5 interpolation": blend(0.5),
            "interpolation (true gap)": interp, "hold last frame": hold}


def score_windows(gdef, params, windows, make, pos_scale):
    """The classifier's mean score on ``windows[L]`` for each L of the in-between frames ``make(b, L)``
    (B, 2, L, J, 9) key space, each after its last context frame, in the common space; with the mean joint speed
    and its standard deviation over time (cm per frame).  -> ([score per L], speed, speed std)."""
    import jax.numpy as jnp

    from inbetween_jax.evaluation.interaction import classify_windows, to_common_space
    score, speed, spread = [], [], []
    for L, b in windows.items():
        prev = np.asarray(to_common_space(jnp.asarray(b["x"][:, :, N_INPUT - 1:N_INPUT]), b["rel_R"], b["rel_t"]))
        pred = np.asarray(to_common_space(jnp.asarray(np.asarray(make(b, L), np.float32)), b["rel_R"], b["rel_t"]))
        clip = np.concatenate([prev, pred], 2)                                           # (B, 2, L + 1, J, 9)
        score.append(float(np.mean(classify_windows(gdef, params, jnp.asarray(clip))[0])))
        v = np.linalg.norm(np.diff(clip[..., :3], axis=2), axis=-1) / pos_scale       # (B, 2, L, J) cm / frame
        speed.append(v.mean())
        spread.append(v.std(2).mean())
    return score, float(np.mean(speed)), float(np.mean(spread))


def classifier_scorer(train, judged, joints, data_cfg, steps: int, lengths=(40, 60, 80)):
    """Train the bench's interaction classifier on the ``train`` pairs (``steps``) and return
    ``score(method) -> float``: its mean score on every ``lengths`` window of the ``judged`` pairs, as a multiple
    of ground truth's."""
    d = data_cfg
    gdef, params, _ = proto.train_classifier(train, train[0].feats.shape[2], joints, steps=steps,
                                             pos_scale=d.pos_scale)
    windows = proto.table1_windows(judged, d.pos_scale, 128, lengths)
    truth = np.mean(score_windows(gdef, params, windows, truth_variants()["ground truth"], d.pos_scale)[0])
    return lambda method: np.mean(score_windows(gdef, params, windows, rollout(method, d.n_pred),
                                                d.pos_scale)[0]) / truth


def mean_rollout(methods):
    """A bench method averaging ``methods``' rollouts (one sample each, drawn with keys split from the call's)."""
    import jax

    def method(b, steps, samples, key):
        keys = jax.random.split(key, len(methods))
        return np.mean([np.asarray(m(b, steps, samples, k)) for m, k in zip(methods, keys)], axis=0)
    return method
