"""Training of the convolutional inpainting AE (Sec. 3.3) on top of the shared driver
:func:`inbetween_jax.train.run_training` (jit, step keys ``fold_in(base, step)``, orbax checkpoints, resume).

Step ``i`` draws ``batch_size`` random 240-frame clips (uniform over every valid start in the training
motions), corrupts them in the jitted step with :func:`~inbetween_jax.models.cae_data.training_mask` (gap of
mean ``mu_e`` or 1-3 joints removed) and minimises the L1 error over the whole clip with Adam.
``epoch = i // steps_per_epoch`` drives the curriculum.

A run folder holds ``checkpoints/`` (state = ``{"params", "opt_state"}``), ``metrics.csv/jsonl`` and
``cae_meta.json`` (config preset + overrides, skeleton, normaliser, data source) so that
:func:`load_trained` can rebuild the model without the training data.
"""
from __future__ import annotations

import json
import math
import os
import time
import warnings
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import nnx

from inbetween_jax.configs.cae import Config, get_config
from inbetween_jax.data import load_motions, resolve_source
from inbetween_jax.data.features import Normalizer
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.models import cae
from inbetween_jax.models.cae_data import ClipBank, build_clip_bank, curriculum_mu, motion_features, training_mask
from inbetween_jax.train import Checkpointer, apply_overrides, config_to_dict, run_training

__all__ = ["prepare_bank", "steps_per_epoch", "total_steps", "build_model", "make_fns", "train",
           "load_trained", "TrainedCAE", "META_FILE"]

META_FILE = "cae_meta.json"


def prepare_bank(source: str | None, cfg: Config, split: str = "train"):
    """Load a split's motions and build the clip bank.  Returns ``(bank, motions, feats)``."""
    motions = load_motions(source, split)
    if cfg.data.max_motions > 0:
        motions = motions[:cfg.data.max_motions]
    feats = [motion_features(m) for m in motions]
    length = cfg.data.clip_length
    longest = max(f.features.shape[0] for f in feats)
    if longest < length:  # e.g. the embedded CMU clips (<= 169 frames): the model is fully convolutional
        length = max(8, longest // 8 * 8)
        warnings.warn(f"no training motion has {cfg.data.clip_length} frames; training on {length}-frame clips")
    return build_clip_bank(feats, length, std_eps=cfg.data.std_eps), motions, feats


def steps_per_epoch(cfg: Config, bank: ClipBank) -> int:
    """``cfg.steps_per_epoch`` or ceil(#clips at ``data.epoch_stride`` / batch_size)."""
    if cfg.steps_per_epoch > 0:
        return int(cfg.steps_per_epoch)
    n = max(1, len(bank.starts[::max(1, cfg.data.epoch_stride)]))
    return max(1, math.ceil(n / cfg.batch_size))


def total_steps(cfg: Config, spe: int) -> int:
    return int(cfg.num_steps) if cfg.num_steps > 0 else int(cfg.num_epochs) * spe


def build_model(cfg: Config, num_features: int, seed: int = 0):
    m = cfg.model
    return cae.make_model(m.variant, num_features, m.channels, m.leak, m.holden_hidden, m.holden_width, seed=seed)


def epoch_mu(cfg: Config, epoch: int) -> float:
    k = cfg.mask
    if not k.curriculum:
        return float(k.fixed_mu)
    return curriculum_mu(epoch, k.mu_start, k.mu_end, k.mu_step, k.every_epochs)


def make_fns(cfg: Config, bank: ClipBank):
    """``(init_fn, train_step_fn, batch_fn, graphdef, spe)`` for :func:`run_training`.

    batch: ``{"x": (B, D, T) normalised clean clips, "mu": () mean gap length of this step's epoch}``.
    state: ``{"params": nnx.State, "opt_state": optax state}``.
    """
    d = bank.frames.shape[1]
    graphdef, _ = nnx.split(build_model(cfg, d))
    tx = optax.adam(cfg.lr)
    spe = steps_per_epoch(cfg, bank)
    k, j, length, bsz = cfg.mask, bank.num_joints, bank.clip_length, cfg.batch_size

    def init_fn(key):
        params = nnx.state(build_model(cfg, d, seed=0), nnx.Param)
        # re-draw every weight from ``key`` with Xavier uniform (biases zero), so the seed decides the init
        leaves, tree = jax.tree.flatten(params)
        keys = jax.random.split(key, len(leaves))
        init = nnx.initializers.xavier_uniform()
        leaves = [init(kk, x.shape, x.dtype) if x.ndim >= 2 else jnp.zeros_like(x) for kk, x in zip(keys, leaves)]
        params = jax.tree.unflatten(tree, leaves)
        return {"params": params, "opt_state": tx.init(params)}

    def train_step_fn(state, batch, key):
        x, mu = batch["x"], batch["mu"]
        mask = training_mask(key, bsz, j, length, mu, k.sigma, k.p_joint, k.max_joints)

        def loss_fn(params):
            y = nnx.merge(graphdef, params)(x * mask)
            return jnp.mean(jnp.abs(y - x)), y

        (loss, y), grads = jax.value_and_grad(loss_fn, has_aux=True)(state["params"])
        updates, opt_state = tx.update(grads, state["opt_state"], state["params"])
        params = optax.apply_updates(state["params"], updates)
        hole = 1.0 - mask
        hole_l1 = jnp.sum(jnp.abs(y - x) * hole) / jnp.maximum(jnp.sum(hole), 1.0)
        return {"params": params, "opt_state": opt_state}, {"loss": loss, "hole_l1": hole_l1, "mu": mu}

    n = len(bank.starts)

    def batch_fn(step, key):
        idx = np.asarray(jax.random.randint(key, (bsz,), 0, n))
        return {"x": bank.clips(idx), "mu": np.float32(epoch_mu(cfg, step // spe))}

    return init_fn, train_step_fn, batch_fn, graphdef, spe


def _write_meta(run_dir, preset, overrides, cfg, bank, motions, source):
    meta = {"preset": preset, "overrides": list(overrides), "config": config_to_dict(cfg),
            "source": source, "skeleton": motions[0].skeleton.to_dict(), "fps": float(motions[0].fps),
            "num_joints": bank.num_joints, "clip_length": bank.clip_length, "normalizer": bank.normalizer.to_dict(),
            "train_motions": [os.path.basename(m.source) for m in motions],
            "train_frames": int(bank.frames.shape[0]), "num_clips": int(len(bank.starts))}
    os.makedirs(run_dir, exist_ok=True)
    tmp = os.path.join(run_dir, META_FILE + ".tmp")
    with open(tmp, "w") as fh:
        json.dump(meta, fh, indent=1)
    os.replace(tmp, os.path.join(run_dir, META_FILE))
    return meta


def train(run_dir: str, source: str | None = None, preset: str = "paper", overrides: Sequence[str] = (),
          progress: bool = True):
    """Train (or resume) a run; returns ``(state, logged_rows, info)`` with wall time and step counts."""
    cfg = apply_overrides(get_config(preset), list(overrides))
    src = resolve_source(source)
    bank, motions, _ = prepare_bank(src, cfg)
    _write_meta(run_dir, preset, overrides, cfg, bank, motions, src)
    init_fn, step_fn, batch_fn, _, spe = make_fns(cfg, bank)
    num = total_steps(cfg, spe)
    t0 = time.time()
    state, logged = run_training(init_fn, step_fn, batch_fn, cfg, run_dir, num, cfg.log_every, cfg.ckpt_every,
                                 cfg.seed, progress=progress)
    info = {"wall_s": time.time() - t0, "steps": num, "steps_per_epoch": spe, "epochs": num / spe,
            "train_frames": int(bank.frames.shape[0]), "clips": int(len(bank.starts))}
    return state, logged, info


class TrainedCAE:
    """A restored model: ``predict(x_norm (B, D, T)) -> (B, D, T)`` (jitted), plus normaliser and metadata."""

    def __init__(self, graphdef, params, normalizer: Normalizer, meta: dict, cfg: Config, step: int):
        self.graphdef, self.params, self.normalizer, self.meta, self.cfg, self.step = (
            graphdef, params, normalizer, meta, cfg, step)
        self.num_joints = int(meta["num_joints"])
        self.skeleton = Skeleton.from_dict(meta["skeleton"])
        self._apply = jax.jit(lambda p, x: nnx.merge(graphdef, p)(x))

    def predict(self, x_norm):
        return self._apply(self.params, jnp.asarray(x_norm, jnp.float32))


def load_trained(run_dir: str, step: int | None = None) -> TrainedCAE:
    """Restore the latest (or ``step``) checkpoint of a run folder written by :func:`train`."""
    with open(os.path.join(run_dir, META_FILE)) as fh:
        meta = json.load(fh)
    cfg = apply_overrides(get_config(meta["preset"]), meta["overrides"])
    d = 3 * int(meta["num_joints"]) + 3
    graphdef, params = nnx.split(build_model(cfg, d))
    tx = optax.adam(cfg.lr)
    target = {"params": params, "opt_state": tx.init(params)}
    ckpt = Checkpointer(os.path.join(os.path.abspath(run_dir), "checkpoints"))
    try:
        step = ckpt.latest_step() if step is None else step
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {run_dir}/checkpoints")
        state = ckpt.restore(step, target)
    finally:
        ckpt.close()
    return TrainedCAE(graphdef, state["params"], Normalizer.from_dict(meta["normalizer"]), meta, cfg, step)
