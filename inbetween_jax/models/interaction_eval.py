"""Evaluation of two-character in-betweening (the paper's Table 1 layout).

* :func:`restore_run` -- config, graphdefs and parameters of a training run folder.
* :func:`interpolation_inbetween` -- the per-character baseline: root / joint-position lerp + rotation slerp
  from the last observed frame to the keypose, each character on its own.
* An independently trained interaction classifier (periodic autoencoder on PJD dynamics + MLP with
  per-character pose statistics), trained on real pairs against "fakes" produced without the model under
  test (time-desynchronised partners, interpolation in-betweens, jittered poses): its probability is the
  interaction score and its hidden features feed the Frechet distance (:func:`frechet_distance`).
"""
from __future__ import annotations

import json
import os

import jax
import jax.numpy as jnp
import numpy as np
import optax
import scipy.linalg
from flax import nnx

from inbetween_jax.geometry import quat_fix_sign, quat_from_forward_up, quat_slerp, quat_to_forward_up
from inbetween_jax.models.interaction_nets import Discriminator, PeriodicAE, pjd_dynamics

CLS_N = 30          # PJD frames per classifier window (paper: N = 30)


# ----------------------------------------------------------------------------- runs
def restore_run(run_dir: str, step=None):
    """-> (cfg, nets, params, meta) of ``run_dir`` (a folder written by experiments/train_interaction.py)."""
    from inbetween_jax.configs.interaction import get_config
    from inbetween_jax.models.interaction_train import make_training
    from inbetween_jax.train import Checkpointer, apply_overrides
    with open(os.path.join(run_dir, "interaction_meta.json")) as f:
        meta = json.load(f)
    cfg = apply_overrides(get_config(meta["variant"]), meta["overrides"])
    nets, init_fn, _, _ = make_training(cfg, meta["num_joints"], meta["forward_axis"])
    ckpt = Checkpointer(os.path.join(run_dir, "checkpoints"))
    try:
        step = ckpt.latest_step() if step is None else step
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {run_dir}")
        state = ckpt.restore(step, jax.eval_shape(init_fn, jax.random.key(0)))
    finally:
        ckpt.close()
    meta["restored_step"] = int(step)
    return cfg, nets, state["params"], meta


# ----------------------------------------------------------------------------- baseline
def interpolation_inbetween(last, keypose, length: int):
    """Per-character interpolation: last (B, 2, J, 9) -> keypose (B, 2, J, 9) over ``length`` frames
    (the keypose itself excluded).  Positions lerp, rotations slerp.  Returns (B, 2, length, J, 9)."""
    last, keypose = jnp.asarray(last), jnp.asarray(keypose)
    t = (jnp.arange(1, length + 1, dtype=jnp.float32) / (length + 1))[:, None]            # (L, 1)
    a, b = last[:, :, None], keypose[:, :, None]                                          # (B, 2, 1, J, 9)
    pos = a[..., :3] + (b[..., :3] - a[..., :3]) * t[..., None]
    qa, qb = quat_from_forward_up(a[..., 3:]), quat_from_forward_up(b[..., 3:])
    shape = pos.shape[:-1]
    q = quat_slerp(jnp.broadcast_to(qa, shape + (4,)), jnp.broadcast_to(qb, shape + (4,)),
                   jnp.broadcast_to(t, shape))
    return jnp.concatenate([pos, quat_to_forward_up(q)], -1)


# ----------------------------------------------------------------------------- metric helpers
def to_common(feats, rel_R, rel_t):
    """Character B's features into character A's key space: (B, 2, T, J, 9) -> same."""
    from inbetween_jax.models.interaction_data import apply_space
    b = apply_space(feats[:, 1], rel_R[:, 1, None], rel_t[:, 1, None])
    return jnp.stack([feats[:, 0], b], 1)


def global_quats(feats, prev):
    """Sign-continuous global quaternions of (..., T, J, 9) features, continuing from ``prev`` (..., J, 9)."""
    q = quat_from_forward_up(jnp.concatenate([prev[..., None, :, :], feats], -3)[..., 3:])
    return quat_fix_sign(q, axis=-3)[..., 1:, :, :]


def frechet_distance(fa: np.ndarray, fb: np.ndarray) -> float:
    """Frechet distance between Gaussians fitted to features fa (N, D) and fb (M, D)."""
    fa, fb = np.asarray(fa, np.float64), np.asarray(fb, np.float64)
    ma, mb = fa.mean(0), fb.mean(0)
    ca, cb = np.cov(fa, rowvar=False), np.cov(fb, rowvar=False)
    covmean = scipy.linalg.sqrtm(ca @ cb)
    covmean = np.real(covmean)
    return float(np.sum((ma - mb) ** 2) + np.trace(ca + cb - 2.0 * covmean))


# ----------------------------------------------------------------------------- interaction classifier
class InteractionClassifier(nnx.Module):
    """Clip (B, 2, N + 1, J, 9) in one space -> (logit (B,), features (B, H))."""

    def __init__(self, num_joints: int, joints, H: int = 64, Cp: int = 8, *, rngs: nnx.Rngs):
        self.joints = tuple(joints) if joints else tuple(range(num_joints))
        c = len(self.joints) ** 2
        self.pae = PeriodicAE(c, CLS_N, Cp, 32, rngs=rngs)
        self.head = Discriminator(CLS_N, Cp, H, extra=2 * num_joints * 4, rngs=rngs)

    def __call__(self, clip):
        pos = clip[..., :3]
        pjd = pjd_dynamics(pos[:, 0], pos[:, 1], self.joints, 1.0)
        recon, h, prm = self.pae(pjd)
        rel = pos - pos[:, :, :, :1] * jnp.asarray([1.0, 0.0, 1.0])                   # root-relative (floor)
        speed = jnp.linalg.norm(pos[:, :, 1:] - pos[:, :, :-1], axis=-1)              # (B, 2, N, J)
        extra = jnp.concatenate([jnp.linalg.norm(rel, axis=-1).mean(2), rel[..., 1].mean(2),
                                 speed.mean(2) * 10, speed.std(2) * 10], -1).reshape(clip.shape[0], -1)
        logit, feat = self.head(h, prm, extra)
        return logit, feat, jnp.mean((recon - pjd) ** 2)


def _real_clips(pairs, rng, n, pos_scale):
    """n random real (2, N + 1, J, 9) clips in world space (positions scaled)."""
    out = []
    lens = np.array([p.num_frames - CLS_N - 1 for p in pairs], np.float64).clip(0)
    for i in rng.choice(len(pairs), n, p=lens / lens.sum()):
        s = rng.integers(0, int(lens[i]))
        out.append(pairs[i].feats[:, s:s + CLS_N + 1])
    c = np.stack(out).astype(np.float32)
    c[..., :3] *= pos_scale
    return c


def _fake_clips(pairs, rng, n, pos_scale):
    """Fakes made without the model under test: desynchronised partner / interpolation / jitter."""
    real = _real_clips(pairs, rng, n, pos_scale)
    fake = real.copy()
    kind = rng.integers(0, 3, n)
    for b in range(n):
        if kind[b] == 0:                                              # partner from another time
            other = _real_clips(pairs, rng, 1, pos_scale)[0]
            fake[b, 1] = other[1] - other[1, :1, :1] * np.array([1, 0, 1] + [0] * 6) \
                + real[b, 1, :1, :1] * np.array([1, 0, 1] + [0] * 6)
        elif kind[b] == 1:                                            # interpolation in-between
            fake[b] = np.asarray(interpolation_inbetween(jnp.asarray(real[b:b + 1, :, 0]),
                                                         jnp.asarray(real[b:b + 1, :, -1]), CLS_N + 1))[0]
        else:                                                         # jittered poses
            fake[b, ..., :3] += rng.normal(0, 0.03, fake[b, ..., :3].shape)
    return fake


def train_classifier(pairs, num_joints: int, joints=(), steps: int = 300, batch: int = 64, seed: int = 0,
                     pos_scale: float = 0.01):
    """Train the evaluation classifier on ``pairs`` (world space); -> (graphdef, params, final accuracy)."""
    rng = np.random.default_rng(seed)
    model = InteractionClassifier(num_joints, joints, rngs=nnx.Rngs(seed))
    gdef, params = nnx.split(model)
    tx = optax.adam(1e-3)
    opt = tx.init(params)

    def loss_fn(p, clips, labels):
        logit, _, rec = nnx.merge(gdef, p)(clips)
        bce = jnp.mean(optax.sigmoid_binary_cross_entropy(logit, labels))
        return bce + rec, jnp.mean((logit > 0) == (labels > 0.5))

    @jax.jit
    def step(p, o, clips, labels):
        (_, acc), g = jax.value_and_grad(loss_fn, has_aux=True)(p, clips, labels)
        u, o = tx.update(g, o, p)
        return optax.apply_updates(p, u), o, acc

    acc = 0.0
    for _ in range(steps):
        clips = np.concatenate([_real_clips(pairs, rng, batch // 2, pos_scale),
                                _fake_clips(pairs, rng, batch // 2, pos_scale)])
        labels = np.concatenate([np.ones(batch // 2), np.zeros(batch // 2)]).astype(np.float32)
        params, opt, acc = step(params, opt, clips, labels)
    return gdef, params, float(acc)


def classify_windows(gdef, params, clip, stride: int = 10):
    """Score a long clip (B, 2, T, J, 9) (common space, T >= N + 1) on all (N + 1)-frame windows with
    ``stride``: -> (probabilities (B, W), features (B, W, H))."""
    T = clip.shape[2]
    starts = list(range(0, T - CLS_N, stride)) or [0]
    wins = jnp.stack([clip[:, :, s:s + CLS_N + 1] for s in starts], 1)             # (B, W, 2, N+1, J, 9)
    B, W = wins.shape[:2]
    logit, feat, _ = jax.jit(lambda p, x: nnx.merge(gdef, p)(x))(params, wins.reshape((B * W,) + wins.shape[2:]))
    return jax.nn.sigmoid(logit).reshape(B, W), feat.reshape(B, W, -1)
