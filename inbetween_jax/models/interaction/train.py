"""Training of the interaction in-betweening model: ``load_data`` and ``make_training`` for
:func:`inbetween_jax.runner.train_model` / :func:`inbetween_jax.train.run_training`.

Per step (Sec. 4.1.3 and 4.2): P autoregressive steps (``lax.scan``) with scheduled sampling, the generator /
refiner / PAE objective (:func:`.losses.generator_objective`; batches from :func:`training_batch`: the
paper's keyframe placement, or some keyframes inside the predicted frames with the keypose held after them) and the discriminator loss on the PAE latents
of real and generated PJD dynamics.  The parameter groups are disjoint and every group only receives
gradients of its own loss, so one Adam over all groups equals independent optimisers.

State: ``{"params": {gen, ref, pae, disc} (nested dicts of arrays), "opt": optax state, "step": int32}``.  With
``model.members`` M > 1 every parameter and optimiser array has a leading member axis and one step trains the M
members independently (each its own batch, key, gradient clip and Adam state).
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax

from inbetween_jax.evaluation.interaction import guess_gap_length
from inbetween_jax.models.interaction.batches import sample_batch
from inbetween_jax.models.interaction.data import PairSet, augmented_pairs, load_pair_set
from inbetween_jax.models.interaction.losses import discriminator_objective, generator_objective
from inbetween_jax.models.interaction.model import init_params, tta_flagged
from inbetween_jax.models.spec import Training
from inbetween_jax.train.optim import make_optimizer
from inbetween_jax.train.remat import check_remat

__all__ = ["BATCH_KEYS", "load_data", "keyframe_index", "training_batch", "init_state", "make_training"]

BATCH_KEYS = ("x", "keypose", "rel_R", "rel_t")


def load_data(cfg, source, split: str = "train") -> PairSet:
    """The ``split`` pairs of ``source`` (real pairs, else constructed ones; see :mod:`.data`), with the
    augmented copies of ``data.tempo`` / ``data.reverse`` (:func:`.data.augmented_pairs`) for the training
    splits (``train`` / ``fit``; never the validation or test pairs)."""
    d = cfg.data
    data = load_pair_set(source, split, d.pair_distance, d.split)
    if split in ("train", "fit") and (d.tempo or d.reverse):
        data = dataclasses.replace(data, pairs=augmented_pairs(data.pairs, source, d.tempo, d.reverse))
    return data


def keyframe_index(x, keypose, tol: float = 1e-4):
    """Index of the first frame of x (B, 2, L, J, 9) equal (to ``tol``) to the keypose (B, 2, J, 9) for both
    characters -> (B,) int; L where no frame is."""
    dist = np.abs(x - keypose[:, :, None]).max(axis=(1, 3, 4))                 # (B, L)
    hit = dist < tol
    return np.where(hit.any(1), hit.argmax(1), x.shape[2])


def training_batch(pairs, rng: np.random.Generator, cfg) -> dict:
    """A training batch of :data:`BATCH_KEYS` (numpy): ``x`` (B, 2, T + P*l, J, 9), ``keypose``, ``rel_R``,
    ``rel_t``, and for timed models (``model.tta`` / ``model.residual``) or ``data.key_inside > 0``
    ``tta`` (B,) float32 = keyframe index - T + 1 (frames from the last input frame to the keyframe).

    With ``data.key_inside`` the last ``round(key_inside * B)`` samples have their keyframe inside the
    predicted frames (index T + 1 .. T + P*l - 1); their frames after the keyframe are replaced by the
    keypose, so the model learns to arrive and stay.  The other samples take the keyframe in
    ``data.key_min .. key_max`` as the paper does.  Without those switches this is exactly one
    :func:`.batches.sample_batch` call.

    With ``data.tta_guess`` (flagged models, :func:`.model.tta_flagged`) each sample's ``tta`` is, with that
    probability, the evaluation's guess from the context frames and the keypose (guessed gap + 1,
    :func:`~inbetween_jax.evaluation.interaction.guess_gap_length`) instead of the truth, and ``tta_known``
    (B,) float32 is 0 there, 1 elsewhere.  The frames (the targets) are the same either way.
    """
    d, m = cfg.data, cfg.model
    T, N, B = d.n_input, d.ar_steps * d.n_pred, cfg.train.batch_size
    n_in = int(round(d.key_inside * B))
    if not (m.tta or m.residual or n_in):
        b = sample_batch(pairs, rng, B, T + N, (d.key_min, d.key_max), d.mirror, d.pos_scale)
        return {k: b[k] for k in BATCH_KEYS}
    parts = []
    if n_in < B:
        parts.append(sample_batch(pairs, rng, B - n_in, max(T + N, d.key_max + 1), (d.key_min, d.key_max),
                                  d.mirror, d.pos_scale))
    if n_in:
        parts.append(sample_batch(pairs, rng, n_in, T + N, (T + 1, T + N - 1), d.mirror, d.pos_scale))
    out = {k: [] for k in BATCH_KEYS + ("tta",)}
    for b in parts:
        idx = keyframe_index(b["x"], b["keypose"])
        if np.any(idx >= b["x"].shape[2]):
            raise ValueError("a training window does not contain its keyframe")
        x = b["x"][:, :, :T + N].copy()
        after = np.arange(T + N)[None, :] >= idx[:, None]                      # (b, T + N)
        x = np.where(after[:, None, :, None, None], b["keypose"][:, :, None], x)
        out["x"].append(x)
        out["tta"].append((idx - T + 1).astype(np.float32))
        for k in ("keypose", "rel_R", "rel_t"):
            out[k].append(b[k])
    out = {k: np.concatenate(v).astype(np.float32) for k, v in out.items()}
    if tta_flagged(cfg):
        guess = guess_gap_length({"x": out["x"][:, :, :T], "keypose": out["keypose"]}, n_input=T)
        told = rng.random(B) < d.tta_guess
        out["tta"] = np.where(told, guess + 1, out["tta"]).astype(np.float32)
        out["tta_known"] = (~told).astype(np.float32)
    return out


def init_state(cfg, num_joints: int, key) -> dict:
    """Fresh training state: ``{"params", "opt", "step"}`` (parameters from :func:`.model.init_params`; with
    ``model.members`` > 1 parameters and optimiser state carry a leading member axis)."""
    params = init_params(key, cfg, num_joints)
    tx_init = make_optimizer(cfg.train).init
    opt = tx_init(params) if cfg.model.members == 1 else jax.vmap(tx_init)(params)
    return {"params": params, "opt": opt, "step": jnp.zeros((), jnp.int32)}


def make_training(cfg, data: PairSet) -> Training:
    """The pure ``init_fn`` / ``step_fn`` / ``batch_fn`` and the run metadata for ``data`` (:func:`load_data`)."""
    tx = make_optimizer(cfg.train)
    d, m = cfg.data, cfg.model
    check_remat(m.remat)
    T, N = d.n_input, d.ar_steps * d.n_pred
    if d.tta_guess > 0 and not m.tta:
        raise ValueError("data.tta_guess needs model.tta (the guess is told through the time-to-arrival input)")
    if m.gan and m.pjd_frames != N:
        raise ValueError(f"model.pjd_frames ({m.pjd_frames}) must equal data.ar_steps * data.n_pred ({N})")
    J = data.num_joints
    fa = np.asarray(data.forward_axis, np.float32)
    pairs = data.pairs
    M = m.members

    def init_fn(key):
        return init_state(cfg, J, key)

    def member_step(params, opt, batch, key, step):
        batch = dict(batch, step=step.astype(jnp.float32))
        grads, (metrics, aux) = jax.grad(generator_objective, has_aux=True)(params, batch, key, cfg, fa)
        if m.gan:
            dl, gd = jax.value_and_grad(discriminator_objective)(params["disc"], params["pae"], aux["pjd_real"],
                                                                 aux["pjd_fake"], cfg, J)
            grads = dict(grads, disc=gd)
            metrics["disc"] = dl
        updates, opt = tx.update(grads, opt, params)
        return optax.apply_updates(params, updates), opt, metrics

    def step_fn(state, batch, key):
        if M == 1:
            params, opt, metrics = member_step(state["params"], state["opt"], batch, key, state["step"])
        else:       # independent members: own parameters, optimiser state, batch and key; mean metrics.  M
            # subgraphs, not a vmap: XLA:CPU runs them side by side on the cores, and a vmapped step (batched
            # dots, grouped convolutions) took 1.2-1.3x as long (docs/results/speed.md)
            keys = jax.random.split(key, M)
            outs = [member_step(*jax.tree.map(lambda v, i=i: v[i], (state["params"], state["opt"], batch)),
                                keys[i], state["step"]) for i in range(M)]
            params, opt, metrics = jax.tree.map(lambda *v: jnp.stack(v), *outs)
            metrics = jax.tree.map(lambda v: jnp.mean(v, axis=0), metrics)
        return {"params": params, "opt": opt, "step": state["step"] + 1}, metrics

    def batch_fn(step, key):
        """One batch (:func:`training_batch`), or with ``model.members`` M > 1 M of them stacked (M, B, ...)."""
        rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).astype(np.uint32))
        if M == 1:
            return training_batch(pairs, rng, cfg)
        batches = [training_batch(pairs, rng, cfg) for _ in range(M)]
        return {k: np.stack([b[k] for b in batches]) for k in batches[0]}

    kind = "constructed" if data.constructed else "real"
    meta = dict(skeleton=data.skeleton.to_dict(), fps=float(pairs[0].fps), stats={},
                data={"pairs": data.all_pairs, "counts": {"pairs": len(data.all_pairs), "split_pairs": len(pairs),
                                                          "frames": data.num_frames},
                      "split": data.split, "fractions": list(d.split), "constructed": data.constructed},
                extra={"num_joints": J, "forward_axis": [float(v) for v in data.forward_axis]})
    copies = len(pairs) - len({p["name"] for p in data.all_pairs} & {p.name for p in pairs})
    augmented = f" (with {copies} tempo / reversed copies)" if copies else ""
    members = f"; {M} members trained side by side, each on its own batches" if M > 1 else ""
    describe = (f"{len(data.all_pairs)} {kind} pairs, {data.num_frames} {data.split} frames{augmented}, "
                f"{J} joints; batches of {cfg.train.batch_size} windows of {T + N} frames{members}")
    return Training(init_fn, step_fn, batch_fn, cfg.train.num_steps, meta, describe)
