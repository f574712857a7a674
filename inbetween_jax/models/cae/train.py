"""Training of the convolutional inpainting AE (Sec. 3.3) for :func:`inbetween_jax.runner.train_model`.

Step ``i`` draws ``train.batch_size`` random clips of ``data.clip_length`` frames (uniform over every valid
start in the training motions), corrupts them in the jitted step with
:func:`~inbetween_jax.models.cae.masks.training_mask` (a gap of mean ``mu_e`` or 1-3 joints removed) and
minimises the L1 error over the whole clip (missing entries weighted ``loss.gap_weight``) with Adam
(:func:`inbetween_jax.train.optim.make_optimizer`).  ``epoch = i // steps_per_epoch`` drives the gap-length
curriculum; with ``data.mask.eval_matched`` the gap lengths switch to the evaluation-matched mixture once the
curriculum has reached ``mu_end`` (from step 0 without a curriculum).  The state is
``{"params": nested dict, "opt_state": optax state}``; ``run.json`` carries the skeleton, the per-row
normaliser (``stats``: mean, std) and ``extra`` (num_joints, clip_length, steps_per_epoch), enough for
:func:`inbetween_jax.models.cae.infer.load` without the training data.
"""
from __future__ import annotations

import dataclasses
import math
import os

import jax
import numpy as np
import optax

from inbetween_jax.data import load_motions
from inbetween_jax.data.resample import WORKING_FPS, check_tempo
from inbetween_jax.models.cae import model
from inbetween_jax.models.cae.features import (ClipBank, body_frame_features, build_clip_bank, mirror_clips,
                                               mirror_rows)
from inbetween_jax.models.cae.losses import masked_l1, weighted_l1
from inbetween_jax.models.cae.masks import curriculum_end_epoch, curriculum_mu, training_mask
from inbetween_jax.models.spec import Training
from inbetween_jax.train.optim import make_optimizer

__all__ = ["ClipData", "load_data", "tempo_copies", "steps_per_epoch", "epoch_mu", "epoch_matched", "make_training"]


@dataclasses.dataclass
class ClipData:
    """What :func:`load_data` returns: the clip bank and the motions it was built from.

    bank: :class:`~inbetween_jax.models.cae.features.ClipBank`; motions: the split's Motions (all of them,
    also those shorter than a clip); split: its name; note: why the clip length differs from the config's
    (empty when it does not).
    """
    bank: ClipBank
    motions: list
    split: str
    note: str = ""


def load_data(cfg, source: str, split: str = "train") -> ClipData:
    """Load a split's motions and build the clip bank (per-row normaliser fitted on them).

    When no motion has ``data.clip_length`` frames (e.g. the embedded CMU clips, <= 169 frames) the clips are
    the longest multiple of 8 frames that fits (the model is fully convolutional); ``note`` says so.
    """
    motions = load_motions(source, split)
    if cfg.data.max_motions > 0:
        motions = motions[:cfg.data.max_motions]
    motions = motions + tempo_copies(source, split, cfg.data.tempo, len(motions))
    feats = [body_frame_features(m) for m in motions]
    length, note = cfg.data.clip_length, ""
    longest = max(f.features.shape[0] for f in feats)
    if longest < length:
        length = max(8, longest // 8 * 8)
        note = f"no training motion has {cfg.data.clip_length} frames; training on {length}-frame clips"
    return ClipData(build_clip_bank(feats, length, std_eps=cfg.data.std_eps), motions, split, note)


def tempo_copies(source: str, split: str, tempo, count: int) -> list:
    """For each speed ``s`` of ``tempo`` (``data.tempo``), the split's first ``count`` motions read at
    ``WORKING_FPS / s`` and played at ``WORKING_FPS``: the same real motion ``s`` times faster.

    Raises:
        ValueError: a speed that is not positive (one line).
    """
    copies = []
    for s in check_tempo(tempo):
        for m in load_motions(source, split, fps=WORKING_FPS / s)[:count]:
            copies.append(dataclasses.replace(m, frame_time=1.0 / WORKING_FPS))
    return copies


def steps_per_epoch(cfg, bank: ClipBank) -> int:
    """``data.steps_per_epoch`` or ceil(#clips at ``data.epoch_stride`` / ``train.batch_size``)."""
    if cfg.data.steps_per_epoch > 0:
        return int(cfg.data.steps_per_epoch)
    n = max(1, len(bank.starts[::max(1, cfg.data.epoch_stride)]))
    return max(1, math.ceil(n / cfg.train.batch_size))


def epoch_mu(cfg, epoch: int) -> float:
    """Mean gap length of ``epoch`` (the curriculum, or ``data.mask.fixed_mu`` without it)."""
    k = cfg.data.mask
    if not k.curriculum:
        return float(k.fixed_mu)
    return curriculum_mu(epoch, k.mu_start, k.mu_end, k.mu_step, k.every_epochs)


def epoch_matched(cfg, epoch: int) -> bool:
    """True when ``epoch`` draws evaluation-matched gap lengths (``data.mask.eval_matched``, after the
    curriculum has reached ``mu_end``; from epoch 0 without a curriculum)."""
    k = cfg.data.mask
    if not k.eval_matched:
        return False
    return not k.curriculum or epoch >= curriculum_end_epoch(k.mu_start, k.mu_end, k.mu_step, k.every_epochs)


def make_training(cfg, data: ClipData) -> Training:
    """The pure pieces for :func:`inbetween_jax.train.run_training` and the run metadata.

    batch: ``{"x": (B, D, T) normalised clean clips, "mu": () mean gap length of this step's epoch,
    "matched": () 1.0 when this epoch draws evaluation-matched gap lengths}``;
    metrics: ``loss`` (weighted L1 over the whole clip), ``hole_l1`` (L1 over the removed entries), ``mu``.
    """
    bank = data.bank
    d = bank.frames.shape[1]
    tx = make_optimizer(cfg.train)
    spe = steps_per_epoch(cfg, bank)
    k, j, length, bsz = cfg.data.mask, bank.num_joints, bank.clip_length, cfg.train.batch_size

    def init_fn(key):
        params = model.init_params(key, cfg, d)
        return {"params": params, "opt_state": tx.init(params)}

    def step_fn(state, batch, key):
        x, mu = batch["x"], batch["mu"]
        mask = training_mask(key, bsz, j, length, mu, k.sigma, k.p_joint, k.max_joints, batch["matched"],
                             tuple(k.matched_frames), k.matched_spread)

        def loss_fn(params):
            y = model.apply(params, x * mask, cfg, mask)
            return weighted_l1(y, x, mask, cfg.loss.gap_weight), y

        (loss, y), grads = jax.value_and_grad(loss_fn, has_aux=True)(state["params"])
        updates, opt_state = tx.update(grads, state["opt_state"], state["params"])
        params = optax.apply_updates(state["params"], updates)
        return {"params": params, "opt_state": opt_state}, {"loss": loss, "hole_l1": masked_l1(y, x, mask), "mu": mu}

    n = len(bank.starts)
    p_mirror = float(cfg.data.mirror)
    # built whenever a switch mirrors, so a rig without left/right names fails now, not at the end of training
    mirror = mirror_rows(data.motions[0].skeleton) if p_mirror > 0 or cfg.model.mirror_average else None

    def batch_fn(step, key):
        idx = np.asarray(jax.random.randint(key, (bsz,), 0, n))
        x = bank.clips(idx)
        if p_mirror > 0:           # its own key, so runs without mirroring draw the clips they always drew
            flip = np.asarray(jax.random.bernoulli(jax.random.fold_in(key, 1), p_mirror, (bsz,)))
            x[flip] = mirror_clips(x[flip], *mirror, bank.normalizer).astype(np.float32)
        return {"x": x, "mu": np.float32(epoch_mu(cfg, step // spe)),
                "matched": np.float32(epoch_matched(cfg, step // spe))}

    motions = data.motions
    meta = {"skeleton": motions[0].skeleton.to_dict(), "fps": float(motions[0].fps),
            "stats": {"mean": bank.normalizer.mean, "std": bank.normalizer.std},
            "data": {"split": data.split, "files": list(dict.fromkeys(os.path.basename(m.source) for m in motions)),
                     "frames": int(bank.frames.shape[0]), "clips": int(n), "clip_length": int(length)},
            "extra": {"num_joints": int(j), "clip_length": int(length), "steps_per_epoch": int(spe)}}
    describe = (f"{n} clips of {length} frames from {len(motions)} motions ({bank.frames.shape[0]} usable frames), "
                f"{spe} steps per epoch, {cfg.model.variant} with "
                f"{model.num_params(jax.eval_shape(init_fn, jax.random.key(0))['params']):,} parameters"
                + (f" ({data.note})" if data.note else ""))
    return Training(init_fn=init_fn, step_fn=step_fn, batch_fn=batch_fn, num_steps=int(cfg.train.num_steps),
                    meta=meta, describe=describe)
