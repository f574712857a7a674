"""Cross-space interaction in-betweening (Zhang et al. 2025): parameters and pure apply functions.

One autoregressive step for both characters (Sec. 4.1)::

    window (B, 2, T, J, 9) in each character's own keyframe space, keypose (B, 2, J, 9)
    pad with the last frame to T + l, DCT over time (K coefficients)            -> (2B, J, K, 9)
    Enc (conv1d + GCN, keypose as extra node input): features h, coarse DCT     (Eq. 1)
    coarse frames -> other character's keyframe space -> its per-frame root space (Eq. 2, T)
    relative features -> DCT -> encoder -> mu, logvar -> z -> FiLM gamma, beta   (Eq. 3)
    h_mod = h * (1 + gamma) + beta; Dec (same architecture) -> residual DCT -> IDCT (Eq. 4)

Parameters are a plain nested dict ``{"gen", "ref", "pae", "disc"}`` of arrays (:func:`init_params`).  The
layers are flax ``nnx`` modules (:mod:`.layers`) used as a layer library: every apply function rebuilds the
module from its static graph definition (:func:`graphdefs`, built once per config and joint count without
allocating) and the dict, so every function here is pure and jit-able.  :func:`rollout` runs the inference
autoregression with ``lax.scan`` and stops once both characters are within ``stop_threshold`` of their
keyposes; :func:`sample_rollouts` draws diverse samples by ``vmap`` over keys.
"""
from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from flax import nnx

from inbetween_jax.geometry import dct, idct
from inbetween_jax.models.interaction.features import apply_space, root_space, to_space
from inbetween_jax.models.interaction.layers import (ConvGCN, Discriminator, FiLM, PeriodicAE, Refiner, film,
                                                     reparameterize)
from inbetween_jax.train.remat import remat_step

__all__ = ["GROUPS", "Generator", "pjd_channels", "graphdefs", "init_params", "cross_space", "cross_space_inverse",
           "extra_features", "tta_features", "lerp_to_keypose", "generator_step", "refine", "pae_encode",
           "pae_reconstruct", "disc_logits", "keypose_distance", "ar_predict", "guess_gap", "speed_guess_gap",
           "tta_flagged", "rollout", "stop_at_keypose", "sample_rollouts"]

GROUPS = ("gen", "ref", "pae", "disc")


class Generator(nnx.Module):
    """The cross-space in-betweening network (Enc, relative encoder + VAE heads, FiLM, Dec)."""

    def __init__(self, num_joints: int, cfg, *, rngs: nnx.Rngs):
        m = cfg.model
        K, H = m.dct_coeffs, m.hidden
        zero = dict(out_init=nnx.initializers.zeros) if m.residual else {}
        self.enc = ConvGCN(num_joints, K, 9, extra_features(cfg), H, K * 9, m.conv_channels, m.gcn_layers,
                           rngs=rngs, **zero)
        if m.interaction:
            self.rel_enc = ConvGCN(num_joints, K, 9, 0, H, 2 * m.latent, m.conv_channels, m.gcn_layers, rngs=rngs)
            self.film = FiLM(m.latent, H, rngs=rngs)
        self.dec = ConvGCN(num_joints, K, 9, H, H, K * 9, m.conv_channels, m.gcn_layers, rngs=rngs, **zero)


TTA_FEATURES = 3


def extra_features(cfg) -> int:
    """Per-joint extra encoder input width: keypose (9) [+ offsets to it (9)] [+ time to arrival (3)
    [+ whether it is the true one (1), with ``data.tta_guess``]]."""
    m = cfg.model
    return 9 + 9 * m.key_offsets + (TTA_FEATURES + tta_flagged(cfg)) * m.tta


def tta_flagged(cfg) -> bool:
    """Whether the time-to-arrival input carries a known / guessed flag (``data.tta_guess`` > 0)."""
    return bool(cfg.model.tta and cfg.data.tta_guess > 0)


def tta_features(tta, n_pred: int, known=None):
    """Time to arrival (B,) frames -> (B, 3): tta / 30 (clipped at 4), exp(-tta / 10), keyframe within this step;
    with ``known`` (B,) (1: the true time, 0: a guess) appended as a 4th feature -> (B, 4)."""
    t = jnp.maximum(tta, 0.0)
    feats = [jnp.minimum(t / 30.0, 4.0), jnp.exp(-t / 10.0), (t <= n_pred).astype(t.dtype)]
    return jnp.stack(feats + ([] if known is None else [known.astype(t.dtype)]), -1)


def lerp_to_keypose(last, keypose, tta, n: int):
    """The residual base: n frames lerping from ``last`` (B, 2, J, 9) toward ``keypose`` (B, 2, J, 9), reaching
    it ``tta`` (B,) frames after ``last`` and holding it afterwards: frame i (1..n) is
    ``last + (keypose - last) min(1, i / tta)``.  -> (B, 2, n, J, 9)."""
    i = jnp.arange(1, n + 1, dtype=last.dtype)
    a = jnp.minimum(1.0, i[None] / jnp.maximum(tta, 1.0)[:, None])          # (B, n)
    a = a[:, None, :, None, None]
    return last[:, :, None] + (keypose - last)[:, :, None] * a


def pjd_channels(num_joints: int, cfg) -> int:
    j = len(cfg.model.pjd_joints) or num_joints
    return j * j


def _modules(key, num_joints: int, cfg) -> dict:
    ks = jax.random.split(key, 4)
    m, d = cfg.model, cfg.data
    return dict(
        gen=Generator(num_joints, cfg, rngs=nnx.Rngs(ks[0])),
        ref=Refiner(num_joints, d.n_pred, m.refiner_hidden, m.refiner_latent, m.conv_channels, m.gcn_layers,
                    rngs=nnx.Rngs(ks[1]), identity_init=m.residual),
        pae=PeriodicAE(pjd_channels(num_joints, cfg), m.pjd_frames, m.pae_channels, m.pae_hidden,
                       rngs=nnx.Rngs(ks[2])),
        disc=Discriminator(m.pjd_frames, m.pae_channels, m.disc_hidden, rngs=nnx.Rngs(ks[3])))


def init_params(key, cfg, num_joints: int) -> dict:
    """-> ``{"gen", "ref", "pae", "disc"}``: each a nested dict of arrays (``nnx.to_pure_dict``).

    With ``model.members`` M > 1 every array gains a leading member axis (M, ...): M networks initialised
    from M keys split from ``key``."""
    one = lambda k: {g: nnx.to_pure_dict(nnx.split(v)[1]) for g, v in _modules(k, num_joints, cfg).items()}  # noqa
    M = cfg.model.members
    if M < 1:
        raise ValueError(f"model.members must be at least 1, not {M}")
    if M == 1:
        return one(key)
    members = [one(k) for k in jax.random.split(key, M)]
    return jax.tree.map(lambda *a: jnp.stack(a), *members)


@functools.lru_cache(maxsize=32)
def _graphs(model_cfg, data_cfg, num_joints: int) -> dict:
    from types import SimpleNamespace
    cfg = SimpleNamespace(model=model_cfg, data=data_cfg)
    mods = nnx.eval_shape(lambda: _modules(jax.random.key(0), num_joints, cfg))
    out = {}
    for k, v in mods.items():
        gdef, state = nnx.split(v)
        out[k] = (gdef, jax.tree.structure(state), jax.tree.structure(nnx.to_pure_dict(state)))
    return out


def graphdefs(cfg, num_joints: int) -> dict:
    """``{group: nnx graph definition}`` of the four parameter groups (static; nothing is allocated)."""
    return {k: v[0] for k, v in _graphs(cfg.model, cfg.data, num_joints).items()}


def _module(group: str, params: dict, cfg, num_joints: int):
    """The nnx module of ``group`` holding the arrays of the plain dict ``params``."""
    gdef, state_def, dict_def = _graphs(cfg.model, cfg.data, num_joints)[group]
    leaves, got = jax.tree.flatten(params)
    if got != dict_def:
        raise ValueError(f"{group} parameters do not match the config (expected {dict_def}, got {got})")
    return nnx.merge(gdef, jax.tree.unflatten(state_def, leaves))


def _to_nodes(c):
    """(B, 2, K, J, C) -> (2B, J, K, C)."""
    B, _, K, J, C = c.shape
    return jnp.moveaxis(c.reshape(2 * B, K, J, C), 1, 2)


def _from_nodes(c, B):
    """(2B, J, K, C) -> (B, 2, K, J, C)."""
    c = jnp.moveaxis(c, 2, 1)
    return c.reshape((B, 2) + c.shape[1:])


def cross_space(coarse, rel_R, rel_t, forward_axis):
    """Eq. 2: each character's frames in the other character's per-frame root space.

    coarse (B, 2, T, J, 9) in own keyframe spaces; rel_R (B, 2, 3, 3), rel_t (B, 2, 3) map character c's key
    space to the other's.  Returns (B, 2, T, J, 9).
    """
    other = coarse[:, ::-1]
    in_other = apply_space(coarse, rel_R[:, :, None], rel_t[:, :, None])
    oR, ot = root_space(other[..., 0, :], forward_axis)                    # (B, 2, T, 3, 3), (B, 2, T, 3)
    return to_space(in_other, oR, ot)


def cross_space_inverse(rel, other, rel_R, rel_t, forward_axis):
    """Inverse of :func:`cross_space` given the other character's frames ``other`` (B, 2, T, J, 9)."""
    oR, ot = root_space(other[..., 0, :], forward_axis)
    in_other = apply_space(rel, oR, ot)
    Rt = jnp.swapaxes(rel_R, -1, -2)
    return apply_space(in_other, Rt[:, :, None], -jnp.einsum("...ij,...j->...i", Rt, rel_t)[:, :, None])


def generator_step(gen_params, window, keypose, rel_R, rel_t, key, cfg, forward_axis, tta=None, latent_scale=1.0,
                   tta_known=None):
    """One prediction step for both characters.

    gen_params: ``params["gen"]``; window (B, 2, T, J, 9), keypose (B, 2, J, 9), rel_R (B, 2, 3, 3),
    rel_t (B, 2, 3), key: PRNG key; tta (B,) frames from the window's last frame to the keyframe (used with
    ``model.tta`` / ``model.residual``; required with ``model.tta``); latent_scale: the latent's noise scale
    (1 in training; inference uses ``model.latent_scale``); tta_known (B,) 1 where ``tta`` is the true time,
    0 where it is a guess (:func:`tta_flagged` models; None: all true).  Returns dict: pred (B, 2, l, J, 9),
    coarse (B, 2, l, J, 9), mu / logvar (B, 2, J, Z) (zeros (B, 2, J, 1) when interaction modelling is off).

    With ``model.residual`` the window is padded with :func:`lerp_to_keypose` (``tta`` frames, else
    ``model.lerp_frames``) instead of its last frame, and the outputs are that padded window plus the network's
    change of the truncated DCT (exactly the lerp while the zero-initialised output layers are zero).
    """
    m, d = cfg.model, cfg.data
    B, _, T, J, _ = window.shape
    gen = _module("gen", gen_params, cfg, J)
    L = T + d.n_pred
    last = window[:, :, -1]
    if m.tta and tta is None:
        raise ValueError("model.tta needs the time to arrival (tta) of every sample")
    if m.residual:
        reach = jnp.full((B,), float(m.lerp_frames), window.dtype) if tta is None else tta.astype(window.dtype)
        base = lerp_to_keypose(last, keypose, reach, d.n_pred)
    else:
        base = jnp.repeat(window[:, :, -1:], d.n_pred, axis=2)
    pad = jnp.concatenate([window, base], axis=2)
    c_in = _to_nodes(dct(pad, axis=2, num_coeffs=m.dct_coeffs))           # (2B, J, K, 9)
    K = c_in.shape[2]
    extra = [keypose]
    if m.key_offsets:
        extra.append(keypose - last)
    if m.tta:
        known = (jnp.ones((B,), window.dtype) if tta_known is None else tta_known) if tta_flagged(cfg) else None
        feats = tta_features(tta.astype(window.dtype), d.n_pred, known)
        extra.append(jnp.broadcast_to(feats[:, None, None], (B, 2, J, feats.shape[-1])))
    extra = jnp.concatenate(extra, -1)
    h, res = gen.enc(c_in, extra.reshape(2 * B, J, -1))
    coarse_c = c_in + res.reshape(2 * B, J, K, 9)
    if m.residual:
        c_base = idct(_from_nodes(c_in, B), n=L, axis=2)
        to_frames = lambda c: pad + (idct(_from_nodes(c, B), n=L, axis=2) - c_base)  # noqa: E731
    else:
        to_frames = lambda c: idct(_from_nodes(c, B), n=L, axis=2)  # noqa: E731
    coarse = to_frames(coarse_c)                                            # (B, 2, L, J, 9)
    if m.interaction:
        rel = cross_space(coarse, rel_R, rel_t, forward_axis)
        _, ml = gen.rel_enc(_to_nodes(dct(rel, axis=2, num_coeffs=m.dct_coeffs)))
        mu, logvar = jnp.split(ml, 2, axis=-1)
        logvar = jnp.clip(logvar, -8.0, 4.0)
        z = reparameterize(mu, logvar, key, latent_scale)
        h = film(h, *gen.film(z))
        mu, logvar = mu.reshape(B, 2, J, -1), logvar.reshape(B, 2, J, -1)
    else:
        mu = logvar = jnp.zeros((B, 2, J, 1), window.dtype)
    _, res2 = gen.dec(coarse_c, h)
    final_c = coarse_c + res2.reshape(2 * B, J, K, 9)
    final = to_frames(final_c)
    return dict(pred=final[:, :, T:], coarse=coarse[:, :, T:], mu=mu, logvar=logvar)


def refine(ref_params, pred, cfg):
    """Motion refiner on a predicted segment: ``params["ref"]``, (B, 2, l, J, 9) -> (B, 2, l, J, 9)."""
    ref = _module("ref", ref_params, cfg, pred.shape[3])
    B = pred.shape[0]
    return ref(pred.reshape((2 * B,) + pred.shape[2:])).reshape(pred.shape)


def pae_encode(pae_params, pjd, cfg, num_joints: int):
    """Periodic latent of PJD dynamics (B, N, C): -> (h (B, N, Cp), {f, a, b, phi} each (B, Cp))."""
    return _module("pae", pae_params, cfg, num_joints).encode(pjd)


def pae_reconstruct(pae_params, pjd, cfg, num_joints: int):
    """Periodic autoencoder: PJD dynamics (B, N, C) -> (reconstruction (B, N, C), h, params)."""
    return _module("pae", pae_params, cfg, num_joints)(pjd)


def disc_logits(pae_params, disc_params, pjd, cfg, num_joints: int):
    """Interaction critic: PJD dynamics (B, N, C) -> PAE latent -> discriminator logits (B,)."""
    h, prm = pae_encode(pae_params, pjd, cfg, num_joints)
    logit, _ = _module("disc", disc_params, cfg, num_joints)(h, prm)
    return logit


def keypose_distance(frame, keypose):
    """Mean joint distance of a frame to the keypose per character: (B, 2, J, 9) x2 -> (B, 2)."""
    return jnp.mean(jnp.linalg.norm(frame[..., :3] - keypose[..., :3], axis=-1), axis=-1)


def ar_predict(gen_params, batch, key, cfg, forward_axis, p_pred):
    """Training autoregression: P = ``data.ar_steps`` steps with scheduled sampling (per-sample
    Bernoulli(p_pred) choice of the prediction over the ground truth as the next input).

    batch: ``x`` (B, 2, T + P*l, J, 9), ``keypose``, ``rel_R``, ``rel_t`` and, for ``model.tta`` /
    ``model.residual``, ``tta`` (B,) frames from the last input frame to the keyframe (step p gets
    ``tta - p l``; with ``data.tta_guess`` ``tta_known`` (B,): 0 where ``tta`` is a guess).
    Returns preds / coarse (B, 2, P*l, J, 9), mu, logvar (P, B, 2, J, Z).
    """
    d, P = cfg.data, cfg.data.ar_steps
    T, l = d.n_input, d.n_pred
    x = batch["x"]
    B = x.shape[0]
    gt = jnp.moveaxis(x[:, :, T:T + P * l].reshape(x.shape[:2] + (P, l) + x.shape[3:]), 2, 0)
    tta0 = batch.get("tta") if (cfg.model.tta or cfg.model.residual) else None

    def step(win, inp):
        g, k, p = inp
        k1, k2 = jax.random.split(k)
        tta = None if tta0 is None else tta0 - p * l
        out = generator_step(gen_params, win, batch["keypose"], batch["rel_R"], batch["rel_t"], k1, cfg,
                             forward_axis, tta, tta_known=batch.get("tta_known"))
        use = jax.random.bernoulli(k2, p_pred, (B, 1, 1, 1, 1))
        nxt = jnp.where(use, out["pred"], g)
        return jnp.concatenate([win[:, :, l:], nxt], axis=2), out

    xs = (gt, jax.random.split(key, P), jnp.arange(P, dtype=jnp.float32))
    _, outs = jax.lax.scan(remat_step(step, cfg.model.remat), x[:, :, :T], xs)
    cat = lambda a: jnp.moveaxis(a, 0, 2).reshape((B, 2, P * l) + a.shape[4:])  # noqa: E731
    return cat(outs["pred"]), cat(outs["coarse"]), outs["mu"], outs["logvar"]


def guess_gap(window, keypose, cfg):
    """A gap length (B,) for timing-conditioned models when none is given, from window (B, 2, T, J, 9) and
    keypose (B, 2, J, 9): the larger of the two characters' mean joint distances to their keyposes (m) /
    ``model.tta_speed``, clipped to [l, ``model.max_frames``].  :func:`tta_flagged` models guess as they were
    trained to be told (:func:`speed_guess_gap`)."""
    m = cfg.model
    if tta_flagged(cfg):
        return speed_guess_gap(window, keypose)
    dist = jnp.max(keypose_distance(window[:, :, -1], keypose), axis=1)
    return jnp.clip(jnp.ceil(dist / m.tta_speed), cfg.data.n_pred, m.max_frames)


def speed_guess_gap(window, keypose, lo: int = 5, hi: int = 200):
    """The evaluation's gap guess (:func:`~inbetween_jax.evaluation.interaction.guess_gap_length`) in jax:
    per character, mean joint distance last frame -> keypose over the mean joint speed of the last 10 frames;
    the larger of the two, rounded, clipped to [lo, hi].  window (B, 2, T >= 11, J, 9) -> (B,) float."""
    x = window[..., :3]
    dist = keypose_distance(x[:, :, -1], keypose)                           # (B, 2)
    speed = jnp.mean(jnp.linalg.norm(jnp.diff(x[:, :, -11:], axis=2), axis=-1), axis=(2, 3))
    return jnp.clip(jnp.round(jnp.max(dist / jnp.maximum(speed, 1e-4), axis=1)), lo, hi)


def rollout(params, window, keypose, rel_R, rel_t, key, cfg, forward_axis, num_steps: int, use_refiner=None,
            threshold=None, gap=None, latent_scale=None, gap_known=True):
    """Inference autoregression with ``lax.scan`` over ``num_steps`` steps of l frames.

    Once both characters' mean joint distance to their keyposes is below ``threshold`` (model units) after
    a step, the sample is done: later frames repeat its last frame (:func:`stop_at_keypose`, on the finished
    frames; a step's prediction depends only on earlier steps, so this equals stopping inside the scan).
    Inputs as :func:`generator_step`;
    ``gap`` (scalar or (B,)): frames to generate before the keyframe, the time-to-arrival input of
    ``model.tta`` / ``model.residual`` models (the keyframe is frame ``gap + 1`` after the window).  Without
    it: ``num_steps * l`` when ``threshold < 0`` (a fixed-length rollout), else :func:`guess_gap`.
    ``gap_known``: False when ``gap`` is a guess (told to :func:`tta_flagged` models; a :func:`guess_gap` is
    always a guess).
    ``use_refiner`` / ``latent_scale``: None = ``model.refiner`` / ``model.latent_scale``.
    Returns (frames (B, 2, num_steps * l, J, 9), length (B,) int32 = frames generated before stopping;
    ``num_steps * l`` when the threshold was never reached).

    With ``model.members`` M > 1 (parameters with a leading member axis, :func:`init_params`) each member
    rolls out the whole gap on its own (``vmap``, one key each), the frames are averaged over the members and
    the stop rule is applied to the mean.  Averaging every step's prediction instead, and feeding the mean
    back, scored worse on the validation take (4.465 against 4.400, docs/results/interaction.md).
    """
    threshold = cfg.model.stop_threshold if threshold is None else threshold
    timed = cfg.model.tta or cfg.model.residual
    if timed and gap is None:
        if threshold < 0:
            gap = num_steps * cfg.data.n_pred
        else:
            gap, gap_known = guess_gap(window, keypose, cfg), False
    one = lambda p, k: _rollout_one(p, window, keypose, rel_R, rel_t, k, cfg, forward_axis, num_steps,  # noqa
                                    use_refiner, gap, latent_scale, gap_known)
    M = cfg.model.members
    frames = one(params, key) if M == 1 else \
        jnp.mean(jax.vmap(one)(params, jax.random.split(key, M)), axis=0)
    return stop_at_keypose(frames, keypose, threshold, cfg.data.n_pred)


def stop_at_keypose(frames, keypose, threshold, l: int):
    """The stop rule on finished rollouts: frames (B, 2, S*l, J, 9), keypose (B, 2, J, 9).  After the first
    l-frame step whose last frame has both characters within ``threshold`` of their keyposes, every frame
    repeats that frame.  -> (frames, length (B,) int32 = frames generated before stopping, S*l when never)."""
    F = frames.shape[2]
    ends = frames[:, :, l - 1::l]                                           # (B, 2, S, J, 9)
    reached = jnp.all(keypose_distance(jnp.moveaxis(ends, 2, 0), keypose[None]) < threshold, axis=2)   # (S, B)
    S = F // l
    first = jnp.where(reached.any(0), jnp.argmax(reached, axis=0), S)       # (B,) step index, S = never
    length = jnp.minimum(first + 1, S) * l
    hold = jnp.take_along_axis(frames, (length - 1)[:, None, None, None, None], axis=2)       # (B, 2, 1, J, 9)
    after = jnp.arange(F)[None] >= length[:, None]                          # (B, F)
    return jnp.where(after[:, None, :, None, None], hold, frames), length.astype(jnp.int32)


def _rollout_one(params, window, keypose, rel_R, rel_t, key, cfg, forward_axis, num_steps: int, use_refiner,
                 gap, latent_scale, gap_known=True):
    """The ``num_steps * l`` frames (B, 2, num_steps * l, J, 9) one network rolls out (``gap`` already resolved;
    no stop rule: :func:`rollout` applies it to the finished frames)."""
    use_refiner = cfg.model.refiner if use_refiner is None else use_refiner
    latent_scale = cfg.model.latent_scale if latent_scale is None else latent_scale
    l = cfg.data.n_pred
    B = window.shape[0]
    timed = cfg.model.tta or cfg.model.residual
    tta0 = jnp.broadcast_to(jnp.asarray(gap, jnp.float32), (B,)) + 1.0 if timed else None
    known = jnp.full((B,), float(gap_known), jnp.float32)

    def step(win, inp):
        k, p = inp
        tta = None if tta0 is None else tta0 - p * l
        pred = generator_step(params["gen"], win, keypose, rel_R, rel_t, k, cfg, forward_axis, tta,
                              latent_scale, known)["pred"]
        if use_refiner:
            pred = refine(params["ref"], pred, cfg)
        return jnp.concatenate([win[:, :, l:], pred], axis=2), pred

    steps = (jax.random.split(key, num_steps), jnp.arange(num_steps, dtype=jnp.float32))
    _, preds = jax.lax.scan(step, window, steps)
    frames = jnp.moveaxis(preds, 0, 2)                                      # (B, 2, S, l, J, 9)
    return frames.reshape(frames.shape[:2] + (num_steps * l,) + frames.shape[4:])


def sample_rollouts(params, window, keypose, rel_R, rel_t, key, cfg, forward_axis, num_steps: int,
                    num_samples: int, **kw):
    """``num_samples`` diverse rollouts by ``vmap`` over keys: (S, B, 2, num_steps * l, J, 9), (S, B)."""
    keys = jax.random.split(key, num_samples)
    return jax.vmap(lambda k: rollout(params, window, keypose, rel_R, rel_t, k, cfg, forward_axis, num_steps,
                                      **kw))(keys)
