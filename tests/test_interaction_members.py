"""Interaction ensembles (``model.members``): members trained side by side are independent networks, a
rollout is the mean of the members' rollouts, and the stop rule on the finished frames matches a numpy
re-derivation.  Real clips: the shipped CMU mocap paired as two characters (constructed pairs)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from inbetween_jax.models.interaction import model as ia
from inbetween_jax.models.interaction.bench import member
from inbetween_jax.models.interaction.config import get_config
from inbetween_jax.models.interaction.infer import Trained
from inbetween_jax.models.interaction.train import load_data, make_training
from inbetween_jax.train import apply_overrides

TIMED = apply_overrides(get_config("tiny"), ["model.residual=true", "model.tta=true", "model.key_offsets=true",
                                             "data.key_inside=0.5"])
PAIR = apply_overrides(TIMED, ["model.members=2"])
GAP = 30


@pytest.fixture(scope="module")
def forward_axis(pair_train):
    return pair_train[0].forward_axis.astype(np.float32)


def _moved(params, key, scale=0.05):
    """Parameters with noise added, so the zero-initialised residual outputs are not zero (not the lerp)."""
    leaves, tree = jax.tree.flatten(params)
    keys = jax.random.split(key, len(leaves))
    return jax.tree.unflatten(tree, [a + scale * jax.random.normal(k, a.shape) for a, k in zip(leaves, keys)])


def _args(windows):
    return (jnp.asarray(windows["x"][:, :, :20]), jnp.asarray(windows["keypose"]), jnp.asarray(windows["rel_R"]),
            jnp.asarray(windows["rel_t"]))


def test_members_get_a_leading_axis_and_their_own_initialisation():
    one = ia.init_params(jax.random.key(0), TIMED, 21)
    two = ia.init_params(jax.random.key(0), PAIR, 21)
    for a, b in zip(jax.tree.leaves(one), jax.tree.leaves(two)):
        assert b.shape == (2,) + a.shape
    k = two["gen"]["enc"]["proj"]["kernel"]
    assert not np.allclose(k[0], k[1])
    with pytest.raises(ValueError, match="members"):
        ia.init_params(jax.random.key(0), apply_overrides(TIMED, ["model.members=0"]), 21)


def _stopped_reference(full, kp, thr, l=10):
    """The stop rule re-derived in numpy: (B, 2, F, J, 9) fixed-length frames -> held frames, lengths."""
    full, kp = np.asarray(full, np.float64), np.asarray(kp, np.float64)
    out, lengths = full.copy(), []
    for i in range(len(full)):
        n = full.shape[2]
        for end in range(l - 1, full.shape[2], l):
            d = np.linalg.norm(full[i, :, end, :, :3] - kp[i, :, :, :3], axis=-1).mean(-1)    # (2,)
            if np.all(d < thr):
                n = end + 1
                break
        out[i, :, n:] = full[i, :, n - 1:n]
        lengths.append(n)
    return out, lengths


def test_stop_rule_holds_the_first_arriving_frame(pair_windows, forward_axis):
    """The rollout stops after the first step whose last frame has both characters within the threshold, and
    repeats that frame (checked against a numpy re-derivation, at thresholds where windows stop at different
    steps or never)."""
    params = _moved(ia.init_params(jax.random.key(0), TIMED, 21), jax.random.key(5))
    w, kp, R, t = _args(pair_windows)
    roll = lambda thr: ia.rollout(params, w, kp, R, t, jax.random.key(2), TIMED, forward_axis, 6,  # noqa: E731
                                  threshold=thr, gap=GAP)
    full, full_len = roll(-1.0)
    assert np.all(np.asarray(full_len) == 60)
    ends = np.sort(np.stack([np.asarray(ia.keypose_distance(full[:, :, s], kp)).max(1) for s in range(9, 60, 10)]),
                   axis=None)
    mids = [(ends[k] + ends[k + 1]) / 2 for k in (len(ends) // 5, len(ends) // 2, 4 * len(ends) // 5)]
    lengths = set()
    for thr in [0.0, 10.0] + mids:            # halfway between two step-end distances: no float ties
        got, got_len = roll(thr)
        ref, ref_len = _stopped_reference(full, kp, thr)
        assert np.asarray(got_len).tolist() == ref_len
        np.testing.assert_allclose(np.asarray(got), ref, atol=1e-6)
        lengths |= set(ref_len)
    assert len(lengths) >= 3                      # stops at different steps, and never (60) at threshold 0


def test_ensemble_rollout_is_the_mean_of_the_members_rollouts(pair_windows, forward_axis):
    params = _moved(ia.init_params(jax.random.key(0), PAIR, 21), jax.random.key(6))
    w, kp, R, t = _args(pair_windows)
    key = jax.random.key(3)
    keys = jax.random.split(key, 2)
    each = [ia.rollout(jax.tree.map(lambda a: a[m], params), w, kp, R, t, keys[m], TIMED, forward_axis, 4,
                       threshold=-1.0, gap=GAP)[0] for m in range(2)]
    assert np.abs(np.asarray(each[0] - each[1])).max() > 1e-2               # the members differ
    mean = (np.asarray(each[0]) + np.asarray(each[1])) / 2
    got, length = ia.rollout(params, w, kp, R, t, key, PAIR, forward_axis, 4, threshold=-1.0, gap=GAP)
    np.testing.assert_allclose(np.asarray(got), mean, atol=1e-5)
    assert np.all(np.asarray(length) == 40)
    first = member(Trained(PAIR, params, 21, forward_axis, None, 0, ""))       # the bench's member row
    assert first.cfg.model.members == 1
    np.testing.assert_array_equal(ia.rollout(first.params, w, kp, R, t, keys[0], first.cfg, forward_axis, 4,
                                             threshold=-1.0, gap=GAP)[0], each[0])
    stopped, stopped_len = ia.rollout(params, w, kp, R, t, key, PAIR, forward_axis, 4, threshold=0.3, gap=GAP)
    ref, ref_len = ia.stop_at_keypose(jnp.asarray(mean), kp, 0.3, TIMED.data.n_pred)
    np.testing.assert_array_equal(np.asarray(stopped_len), np.asarray(ref_len))
    np.testing.assert_allclose(np.asarray(stopped), np.asarray(ref), atol=1e-5)


def test_members_train_independently():
    """One ensemble step = each member's own single-network step on its own batch and key."""
    data = load_data(TIMED, "embedded", "train")
    single, pair = make_training(TIMED, data), make_training(PAIR, data)
    state = pair.init_fn(jax.random.key(0))
    batch = pair.batch_fn(0, jax.random.key(1))
    B = TIMED.train.batch_size
    assert batch["x"].shape[:2] == (2, B) and not np.array_equal(batch["x"][0], batch["x"][1])
    key = jax.random.key(7)
    new, metrics = jax.jit(pair.step_fn)(state, batch, key)
    assert all(np.ndim(v) == 0 for v in metrics.values())
    step_one = jax.jit(single.step_fn)
    member = lambda tree, m: jax.tree.map(lambda a: a[m], tree)  # noqa: E731
    for m, k in enumerate(jax.random.split(key, 2)):
        own = {"params": member(state["params"], m), "opt": member(state["opt"], m), "step": state["step"]}
        ref, _ = step_one(own, {n: v[m] for n, v in batch.items()}, k)
        for a, b in zip(jax.tree.leaves(ref["params"]), jax.tree.leaves(member(new["params"], m))):
            np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-4, atol=1e-6)
    moved = [max(np.abs(np.asarray(a) - np.asarray(b)).max() for a, b in
                 zip(jax.tree.leaves(member(new["params"], m)["gen"]), jax.tree.leaves(member(state["params"], m)["gen"])))
             for m in range(2)]
    assert min(moved) > 1e-4                                                  # both members learn
