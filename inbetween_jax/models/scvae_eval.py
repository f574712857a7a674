"""S-CVAE inference on benchmark windows: load a trained run, sample N transitions per keyframe pair.

All N samples of a chunk of windows come from one compiled call (``vmap`` over PRNG keys of the
``lax.scan`` rollout, see :func:`inbetween_jax.models.scvae.sample`).
"""
from __future__ import annotations

import functools
import json
import os

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.configs.scvae import config_from_dict
from inbetween_jax.models import scvae
from inbetween_jax.models.scvae_losses import fk_positions
from inbetween_jax.models.scvae_train import compute_stats, make_init_fn


def find_checkpoints(ckpt_dir: str) -> str:
    """``ckpt_dir`` may be a run folder (with ``checkpoints/``) or the checkpoints folder itself."""
    sub = os.path.join(ckpt_dir, "checkpoints")
    return sub if os.path.isdir(sub) else ckpt_dir


def load_run(ckpt_dir: str, train_windows, step: int | None = None):
    """Restore (config, state, step) of a training run; ``train_windows`` provide the feature statistics'
    shapes (the restored state carries the trained run's own statistics)."""
    from inbetween_jax.train import Checkpointer
    ck = Checkpointer(find_checkpoints(ckpt_dir))
    try:
        step = ck.latest_step() if step is None else step
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {ckpt_dir!r}")
        cfg = config_from_dict(ck.restore_extra(step)["config"])
        init_fn = make_init_fn(cfg, compute_stats(train_windows), int(train_windows.local_quats.shape[2]))
        state = ck.restore(step, jax.eval_shape(init_fn, jax.random.key(0)))
    finally:
        ck.close()
    return cfg, state, step


@functools.partial(jax.jit, static_argnames=("cfg", "max_length", "parents"))
def _sample_chunk(params, stats, start, target, keys, cfg, max_length, parents):
    res = scvae.sample(params, cfg, stats, start, target, max_length, keys, max_length)
    out = res["out"]
    mid = max_length // 2
    extra = {}
    if cfg.bidirectional:  # raw forward / backward poses at the middle frame (MMPE)
        pf = fk_positions(res["fwd"]["q"][:, :, mid - 1], res["fwd"]["r"][:, :, mid - 1], stats, parents)
        pb = fk_positions(res["bwd"]["q"][:, :, max_length - 1 - mid], res["bwd"]["r"][:, :, max_length - 1 - mid],
                          stats, parents)
        extra = {"mid_f": pf, "mid_b": pb}
    return {"q": out["q"][:, :, 1:max_length], "r": out["r"][:, :, 1:max_length], **extra}


def sample_transitions(cfg, state, windows, n_past: int, n_trans: int, num_samples: int, seed: int = 0,
                       chunk: int = 128) -> dict:
    """Transitions between frame ``n_past - 1`` and frame ``n_past + n_trans`` of every window.

    Returns q (S, B, n_trans, J, 4), r (S, B, n_trans, 3) and, for the bi-directional model, mid_f / mid_b
    (S, B, J, 3) raw forward / backward FK positions at the middle frame.
    """
    length = n_trans + 1
    keys = jax.random.split(jax.random.key(seed), num_samples)
    parts = []
    k0, k1 = n_past - 1, n_past + n_trans
    for lo in range(0, len(windows), chunk):
        sl = slice(lo, lo + chunk)
        start = {"q": windows.local_quats[sl, k0], "r": windows.root_pos[sl, k0], "c": windows.contacts[sl, k0]}
        target = {"q": windows.local_quats[sl, k1], "r": windows.root_pos[sl, k1], "c": windows.contacts[sl, k1]}
        start = jax.tree.map(jnp.asarray, start)
        target = jax.tree.map(jnp.asarray, target)
        parts.append(jax.device_get(_sample_chunk(state["params"], state["stats"], start, target, keys, cfg,
                                                  length, tuple(windows.parents))))
    return {k: np.concatenate([p[k] for p in parts], axis=1) for k in parts[0]}


def run_info(ckpt_dir: str) -> dict:
    path = os.path.join(ckpt_dir, "run.json")
    if os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    return {}
