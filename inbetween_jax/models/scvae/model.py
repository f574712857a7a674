"""S-CVAE: bi-directional stitching CVAE for motion in-betweening (networks, phase network, generator rollout).

Frames are dicts of arrays (see :mod:`inbetween_jax.models.scvae.features`); ``stats`` come from
:func:`~inbetween_jax.models.scvae.features.compute_stats`.  Generators are pure functions of a param pytree
(nested dicts of arrays, :func:`init_params`); the whole bi-directional rollout is one ``lax.scan``
(:func:`rollout`), and :func:`sample` draws N transitions for one batch of keyframe pairs with ``vmap`` over
PRNG keys.

Phase prediction (paper 3.3).  A phase network (MLP) maps (local quaternions, normalised root velocity,
contacts, current phase vector) to a phase *update*; phase_{t+1} = phase_t + update, autoregressively as in
[36].  The keyframe's phase is predicted from the keyframe with a zero phase input.  The network is trained by
its own L1 regression loss on the labels (teacher forcing, :func:`inbetween_jax.models.scvae.losses.phase_loss`)
and receives no gradient from the generator losses, which matches the paper's pre-trained phase network while
training in the same step.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from inbetween_jax.geometry import quat_normalize
from inbetween_jax.geometry.quaternion import quat_align
from inbetween_jax.models.scvae import layers as nn
from inbetween_jax.models.scvae import motion_latent as ML
from inbetween_jax.models.scvae.base_path import base_path, interpolation_path  # noqa: F401 (re-exported)
from inbetween_jax.models.scvae.features import (PHASE_DIM, dims, offset_features, reverse_time,
                                                 state_features)
from inbetween_jax.train.remat import remat_step


def init_phase_net(f: nn.ParamFactory, d_in: int, hidden: int) -> list:
    """MLP (state features + 4 phase) -> hidden -> hidden -> 4 phase update."""
    return nn.init_mlp(f, (d_in, hidden, hidden, PHASE_DIM))


def phase_step(params: list, frame: dict, stats: dict) -> jnp.ndarray:
    """phase_{t+1} = phase_t + net([state_t, phase_t]).  frame needs q, v, c, phase (B, ...); returns (B, 4)."""
    x = jnp.concatenate([state_features(frame, stats), frame["phase"]], -1)
    return frame["phase"] + nn.mlp(params, x)


def init_generator(f: nn.ParamFactory, cfg, num_joints: int) -> dict:
    """Parameters of one S-CVAE generator (encoder, decoder, phase network) declared on ``f``. cfg: ModelConfig."""
    d = dims(num_joints)
    e, o = cfg.enc_hidden, cfg.enc_out
    enc = {"state": nn.init_mlp(f, (d["state"], e, e, o)),
           "offset": nn.init_mlp(f, (d["offset"], e, e, o)),
           "target": nn.init_mlp(f, (d["target"], e, e, o)),
           "head_cur": nn.init_mlp(f, (cfg.lstm_hidden, cfg.head_hidden, 2 * cfg.latent_dim)),
           "head_tgt": nn.init_mlp(f, (cfg.lstm_hidden, cfg.head_hidden, 2 * cfg.latent_dim))}
    if cfg.encoder_lstm:
        enc["lstm"] = nn.init_lstm(f, 3 * o, cfg.lstm_hidden)
    else:
        enc["mlp"] = nn.init_mlp(f, (3 * o, cfg.lstm_hidden))
    dec_in = cfg.latent_dim + cfg.motion_latent + (3 if cfg.decoder_target else 2) * o
    n_exp = cfg.num_experts if cfg.phase_moe else 1
    dec = {"lstm": nn.init_lstm(f, dec_in, cfg.dec_lstm_hidden),
           "experts": nn.init_moe(f, (cfg.dec_lstm_hidden,) + tuple(cfg.expert_hidden) + (d["out"],), n_exp,
                                  zero_last=cfg.residual)}
    if cfg.phase_moe:
        dec["gating"] = nn.init_mlp(f, (PHASE_DIM,) + tuple(cfg.gating_hidden) + (cfg.num_experts,))
    return {"enc": enc, "dec": dec, "phase": init_phase_net(f, d["state"] + PHASE_DIM, cfg.phase_hidden)}


def pack_generator(p: dict) -> dict:
    """Generator params with the decoder LSTM packed for one ``[x, h] @ [wx; wh]`` matmul per step and
    the experts' layers packed side by side (one matmul per layer).  Same values, fewer and larger GEMMs."""
    return dict(p, dec=dict(p["dec"], lstm=nn.pack_lstm(p["dec"]["lstm"]), experts=nn.pack_moe(p["dec"]["experts"])))


def init_carry(cfg, batch: int):
    """Recurrent state of one generator: encoder and decoder LSTM carries."""
    return {"enc": nn.lstm_zero_carry((batch,), cfg.lstm_hidden),
            "dec": nn.lstm_zero_carry((batch,), cfg.dec_lstm_hidden)}


# ----------------------------------------------------------------------------- one generator step
def encode(p: dict, cfg, carry, cur: dict, tgt: dict, tta, gamma, key, stats: dict, taps=None, rec=None):
    """S-CVAE encoder (Fig. 3) for one step.

    Stage 1 embeds (current, offset, target) -> LSTM -> N(mu, sigma); stage 2 replaces the current frame
    by the target (offset 0, tta 0) -> the same LSTM from the same carry -> N(mu_t, sigma_t).  Latent
    interpolation (Eq. 1) blends the two distributions' parameters with ``gamma`` (B,) and z is sampled.
    Returns (new_enc_carry, z (B, Z), kl (B, Z) per latent dimension, state_emb (B, O), target_emb (B, O),
    offset_emb (B, O)).  ``taps`` / ``rec``:
    deferred weight gradients of the LSTM (see :func:`rollout`); the matmul inputs are stored in ``rec``.
    """
    tgt_q = quat_align(tgt["q"], cur["q"])
    b = cur["q"].shape[0]
    emb = nn.tta_embedding(jnp.minimum(tta, cfg.tta_max), cfg.enc_out, cfg.tta_basis)
    emb0 = nn.tta_embedding(jnp.zeros_like(tta), cfg.enc_out, cfg.tta_basis)
    t_raw = nn.mlp(p["target"], tgt_q.reshape(b, -1))
    tgt_state = dict(tgt, q=tgt_q)
    # stage 1 (current frame) and stage 2 (target as current) share the state MLP: one call over 2B rows
    s12 = nn.mlp(p["state"], jnp.concatenate([state_features(cur, stats), state_features(tgt_state, stats)]))
    s1, s2 = s12[:b] + emb, s12[b:] + emb0
    o1 = nn.mlp(p["offset"], offset_features(cur, tgt_q, tgt["r"], stats)) + emb
    # the target's offset to itself is exactly zero: its embedding is one row, broadcast
    zero_off = jnp.zeros((1, 3 + tgt_q.shape[1] * 4), s1.dtype)
    o2 = nn.mlp(p["offset"], zero_off) + emb0
    t1 = t_raw + emb
    t2 = t_raw + emb0
    x1 = jnp.concatenate([s1, o1, t1], -1)
    x2 = jnp.concatenate([s2, o2, t2], -1)
    if cfg.encoder_lstm:
        new_carry, h1, h2 = nn.lstm_shared_carry(p["lstm"], carry, x1, x2, taps)
        if rec is not None:
            rec.update(enc_wh=carry[0], enc_wx=jnp.concatenate([x1, x2], axis=0))
    else:
        new_carry = carry
        h1, h2 = jax.nn.elu(nn.mlp(p["mlp"], x1)), jax.nn.elu(nn.mlp(p["mlp"], x2))
    mu_c, lv_c = jnp.split(nn.mlp(p["head_cur"], h1), 2, -1)
    mu_t, lv_t = jnp.split(nn.mlp(p["head_tgt"], h2), 2, -1)
    lv_c, lv_t = jnp.clip(lv_c, -10.0, 5.0), jnp.clip(lv_t, -10.0, 5.0)
    g = gamma[:, None]
    mu = (1.0 - g) * mu_c + g * mu_t
    sigma = (1.0 - g) * jnp.exp(0.5 * lv_c) + g * jnp.exp(0.5 * lv_t)
    z = mu + sigma * jax.random.normal(key, mu.shape, mu.dtype)
    kl = 0.5 * (mu ** 2 + sigma ** 2 - 1.0 - 2.0 * jnp.log(sigma + 1e-8))
    return new_carry, z, kl, s1, t1, o1


def decode(p: dict, cfg, carry, z, embs: tuple, cur: dict, stats: dict, base=None, taps=None, rec=None):
    """S-CVAE decoder (Fig. 5): LSTM over [z, state emb, target emb] (16 + 256 + 256 = 528 wide; with
    ``cfg.decoder_target`` also the offset emb), then the phase-gated mixture of experts (``p`` packed by
    :func:`pack_generator`).  Paper: predicts root velocity, local-quaternion updates and contacts.  With
    ``cfg.residual`` the same outputs are offsets from ``base`` (the Slerp / lerp frame {q (B, J, 4),
    r (B, 3)} between the keyframes at the time being generated): q = normalize(base q + dq), r = base r + dr.
    Returns (new_dec_carry, next_frame without phase)."""
    b, j = cur["q"].shape[:2]
    taps = taps or {}
    x = jnp.concatenate((z,) + tuple(embs), -1)
    new_carry, h = nn.lstm_packed(p["lstm"], carry, x, taps.get("dec_w"))
    if cfg.phase_moe:
        alpha = jax.nn.softmax(nn.mlp(p["gating"], jax.lax.stop_gradient(cur["phase"])), -1)
    else:
        alpha = jnp.ones((b, 1), h.dtype)
    out = nn.moe(p["experts"], h, alpha, taps.get("moe0"))
    if rec is not None:
        rec.update(dec_w=jnp.concatenate([x, carry[0]], -1), moe0=h)
    dq = out[:, :4 * j].reshape(b, j, 4)
    c = jax.nn.sigmoid(out[:, 4 * j + 3:])
    if cfg.residual:
        q = quat_normalize(quat_align(base["q"], cur["q"]) + dq)
        r = base["r"] + out[:, 4 * j:4 * j + 3] * stats["off_std"]
        return new_carry, {"q": q, "r": r, "v": r - cur["r"], "c": c}
    v = out[:, 4 * j:4 * j + 3] * stats["v_std"]
    q = quat_normalize(cur["q"] + dq)
    return new_carry, {"q": q, "r": cur["r"] + v, "v": v, "c": c}


def generator_step(p: dict, cfg, carry, cur: dict, tgt: dict, tta, gamma, key, stats: dict, base=None, taps=None,
                   rec=None, motion=None):
    """f_{i+1} = G(f_i | f_target).  Returns (new_carry, next_frame (with phase), kl (B, Z)).
    ``base``: the interpolated frame for the residual decoder; ``taps`` / ``rec``: deferred weight
    gradients (see :func:`rollout`); ``motion`` (B, M): the transition's motion latent
    (:mod:`.motion_latent`), given to the decoder beside z."""
    enc_carry, z, kl, s_emb, t_emb, o_emb = encode(p["enc"], cfg, carry["enc"], cur, tgt, tta, gamma, key, stats,
                                                   taps, rec)
    if motion is not None:
        z = jnp.concatenate([z, motion], -1)
    embs = (s_emb, t_emb, o_emb) if cfg.decoder_target else (s_emb, t_emb)
    dec_carry, nxt = decode(p["dec"], cfg, carry["dec"], z, embs, cur, stats, base, taps, rec)
    nxt["phase"] = phase_step(jax.lax.stop_gradient(p["phase"]), cur, stats)
    return {"enc": enc_carry, "dec": dec_carry}, nxt, kl


def gamma_schedule(n, h, k):
    """Eq. 2: gamma = n / floor(L/2) for n < floor(L/2), n / (floor(L/2) + K) for floor(L/2) <= n <= floor(L/2)+K.

    n: step index (current frame), h = floor(L/2), k = K (ints or int arrays)."""
    n = jnp.asarray(n, jnp.float32)
    return jnp.where(n < h, n / jnp.maximum(h, 1), n / (h + k))


def split_sizes(length, buffer_k: int):
    """h = floor(L/2) and the effective buffer K = clip(buffer_k, 1, h - 1) for L frames between keyframes."""
    h = length // 2
    return h, jnp.clip(buffer_k, 1, jnp.maximum(h - 1, 1))


def num_scan_steps(cfg, max_length: int) -> int:
    """Static scan length for transitions of up to ``max_length`` frames between keyframes."""
    return max_length // 2 + cfg.buffer_k if cfg.bidirectional else max_length - 1


# ----------------------------------------------------------------------------- bi-directional rollout
def _select(pred, a: dict, b: dict) -> dict:
    """Per-field where(pred, a, b) for scalar pred."""
    return {k: jnp.where(pred, a[k], b[k]) for k in a}


def rollout(params: dict, cfg, stats: dict, start: dict, target: dict, length, key, max_length: int,
            taps=None, motion=None):
    """Generate the transition between two keyframes ``length`` frames apart (L in the paper).

    start / target: frames at times 0 and L (``v``, the root's displacement from the previous frame, used only
    with ``cfg.start_velocity``; ``qp``, the previous frame's local quaternions, only with ``cfg.base_velocity``
    (:mod:`~inbetween_jax.models.scvae.base_path`); ``phase`` ignored: each generator's phase network estimates it
    from the keyframe).  length: int scalar (traced,
    4 <= L <= max_length).  max_length: static bound fixing every array shape.
    Forward and backward generators (``params["fwd"]``, ``params["bwd"]``) alternate inside one
    ``lax.scan`` (Eq. 3, bi-directional aligning), each producing floor(L/2)+K frames; :func:`stitch`
    blends them.  Returns a dict with
      ``fwd`` / ``bwd``: frames (B, S, ...) in generation order (fwd step m = frame m+1, bwd step m =
      frame L-1-m), ``kl_fwd`` / ``kl_bwd`` (B, S, Z) per latent dimension, ``seam`` (B,)
      (:func:`seam_mismatch`), ``valid`` (S,) bool, ``out``: stitched frames
      (B, max_length+1, ...) for times 0..max_length (times > L repeat the target), ``h``, ``k``.
    taps: optional ``{"fwd": {name: (S, rows, cols) zeros}, "bwd": ...}`` from
    :func:`~inbetween_jax.models.scvae.deferred_grads.make_taps`: the largest matmuls then leave their weight
    gradient to the caller and the result also holds ``rec_fwd`` / ``rec_bwd``: their inputs per step,
    {name: (S, rows, d_in)}.
    motion: (B, M) the transition's motion latent (``cfg.motion_latent`` > 0, :mod:`.motion_latent`); None
    draws it from the learned prior with ``key`` (:func:`.motion_latent.prior_draws`, as :func:`sample` does).
    """
    steps = num_scan_steps(cfg, max_length)
    b = start["q"].shape[0]
    if cfg.motion_latent and motion is None:
        key, km = jax.random.split(key)
        motion = ML.prior_draws(params["fwd"]["motion"], cfg, stats, start, target, length, km[None])[0]
    params = {name: pack_generator(g) for name, g in params.items()}   # once, outside the scan
    h, k = split_sizes(length, cfg.buffer_k)
    zero_v = jnp.zeros_like(start["r"])
    # the paper's keyframe carries no velocity; cfg.start_velocity uses the past frame's (start["v"])
    s0 = dict(start, v=start["v"] if cfg.start_velocity and "v" in start else zero_v)
    t0 = dict(target, v=zero_v)
    s0 = {n: s0[n] for n in ("q", "r", "c", "v")}
    t0 = {n: t0[n] for n in ("q", "r", "c", "v")}
    base_q, base_r = base_path(start, target, length, max_length, cfg.base_velocity,
                               cfg.base_damping)   # (B, T1, J, 4), (B, T1, 3)
    s0["phase"] = phase_step(jax.lax.stop_gradient(params["fwd"]["phase"]), dict(s0, phase=jnp.zeros((b, PHASE_DIM))),
                             stats)
    carry_f = init_carry(cfg, b)
    if cfg.bidirectional:
        t0["phase"] = phase_step(jax.lax.stop_gradient(params["bwd"]["phase"]),
                                 dict(t0, phase=jnp.zeros((b, PHASE_DIM))), stats)
        carry_b = init_carry(cfg, b)
    else:
        t0["phase"] = jnp.zeros((b, PHASE_DIM))
        carry_b = None
    keys = jax.random.split(key, steps)
    ones = jnp.ones((b,), jnp.float32)
    taps = taps or {}

    def body(carry, xs):
        n, step_key, tap = xs
        rec_f, rec_b = ({}, {}) if tap else (None, None)
        kf, kb = jax.random.split(step_key)
        (cf, cur_f), (cb, cur_b) = carry
        if cfg.bidirectional:
            aligned = (n < h) if cfg.aligning else jnp.array(False)
            tgt_f = _select(aligned, reverse_time(cur_b), t0)
            tta_f = jnp.where(aligned, length - 2 * n, length - n)
            gam_f = gamma_schedule(n, h, k) if cfg.latent_interp else 0.0
        else:
            tgt_f, tta_f = t0, length - n
            gam_f = n / jnp.maximum(length - 1, 1) if cfg.latent_interp else 0.0
        tf = jnp.minimum(n + 1, max_length)
        base_f = {"q": base_q[:, tf], "r": base_r[:, tf]}
        cf, nxt_f, kl_f = generator_step(params["fwd"], cfg, cf, cur_f, tgt_f, tta_f * ones, gam_f * ones, kf, stats,
                                         base_f, tap.get("fwd"), rec_f, motion)
        out = {"fwd": nxt_f, "kl_fwd": kl_f}
        if cfg.bidirectional:
            tgt_b = _select(aligned, reverse_time(nxt_f), reverse_time(s0))
            tta_b = jnp.where(aligned, length - 2 * n - 1, length - n)
            tb = jnp.clip(length - 1 - n, 0, max_length)
            base_b = {"q": base_q[:, tb], "r": base_r[:, tb]}
            cb, nxt_b, kl_b = generator_step(params["bwd"], cfg, cb, cur_b, tgt_b, tta_b * ones, gam_f * ones, kb,
                                             stats, base_b, tap.get("bwd"), rec_b, motion)
            out.update(bwd=nxt_b, kl_bwd=kl_b)
            cur_b = nxt_b
        rec = {"fwd": rec_f, "bwd": rec_b} if tap else {}
        return ((cf, nxt_f), (cb, cur_b)), (out, {k: v for k, v in rec.items() if v})

    init = ((carry_f, s0), (carry_b, reverse_time(t0)))
    _, (ys, recs) = jax.lax.scan(remat_step(body, cfg.remat), init, (jnp.arange(steps), keys, taps))
    ys = jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), ys)  # (B, S, ...)
    m = jnp.arange(steps)
    res = dict(ys, h=h, k=k, **{f"rec_{g}": r for g, r in recs.items()})
    if cfg.bidirectional:
        res["valid"] = (m < h + k) & (m + 1 <= length - 1)
        res["out"] = stitch(start, target, ys["fwd"], reverse_time(ys["bwd"]), length, h, k, max_length)
        res["seam"] = seam_mismatch(ys["fwd"], ys["bwd"], length, h, k, stats)
    else:
        res["valid"] = m < length - 1
        res["out"] = forward_only(start, target, ys["fwd"], length, max_length)
    return res


def seam_mismatch(fwd: dict, bwd: dict, length, h, k, stats: dict):
    """How far apart the two generators are where they are blended (times h-K+1 .. h+K): mean |q_f - q_b|
    over joints plus |r_f - r_b| / pos_unit.  fwd / bwd (B, S, ...) in generation order -> (B,)."""
    steps = fwd["q"].shape[1]
    t = jnp.arange(1, steps + 1)
    bi = jnp.clip(length - 1 - t, 0, steps - 1)
    bq = quat_align(_gather_time(bwd["q"], bi), fwd["q"])
    d = (jnp.mean(jnp.abs(fwd["q"] - bq), axis=(-1, -2))
         + jnp.mean(jnp.abs(fwd["r"] - _gather_time(bwd["r"], bi)), -1) / stats["pos_unit"])
    mask = ((t >= h - k + 1) & (t <= h + k)).astype(d.dtype)
    return jnp.sum(d * mask, -1) / jnp.maximum(jnp.sum(mask), 1.0)


def _gather_time(x, idx):
    """x (B, S, ...), idx (T,) -> (B, T, ...)."""
    return jnp.take(x, idx, axis=1)


def stitch(start: dict, target: dict, fwd: dict, bwd: dict, length, h, k, max_length: int) -> dict:
    """Blend forward and backward sequences over the 2K-frame buffer around the middle.

    Time t in 0..max_length: t = 0 is ``start``; 1 <= t <= h-K forward frames; h-K < t <= h+K a linear
    blend with backward weight (t - (h - K)) / (2K + 1); h+K < t < L backward frames; t >= L is exactly
    ``target``.  fwd / bwd: (B, S, ...) in generation order.  Returns q (B, T, J, 4), r (B, T, 3), c (B, T, 4).
    """
    steps = fwd["q"].shape[1]
    t = jnp.arange(max_length + 1)
    fi = jnp.clip(t - 1, 0, steps - 1)
    bi = jnp.clip(length - 1 - t, 0, steps - 1)
    w = jnp.clip((t - (h - k)).astype(jnp.float32) / (2 * k + 1).astype(jnp.float32), 0.0, 1.0)
    fq, bq = _gather_time(fwd["q"], fi), _gather_time(bwd["q"], bi)
    bq = quat_align(bq, fq)
    wq = w[None, :, None, None]
    q = quat_normalize((1 - wq) * fq + wq * bq)
    wr = w[None, :, None]
    r = (1 - wr) * _gather_time(fwd["r"], fi) + wr * _gather_time(bwd["r"], bi)
    c = (1 - wr) * _gather_time(fwd["c"], fi) + wr * _gather_time(bwd["c"], bi)
    return _with_keyframes(start, target, {"q": q, "r": r, "c": c}, t, length)


def forward_only(start: dict, target: dict, fwd: dict, length, max_length: int) -> dict:
    """"w/o BS": frames 1..L-1 are the forward generator's; the target keyframe is appended as given."""
    steps = fwd["q"].shape[1]
    t = jnp.arange(max_length + 1)
    fi = jnp.clip(t - 1, 0, steps - 1)
    seq = {n: _gather_time(fwd[n], fi) for n in ("q", "r", "c")}
    return _with_keyframes(start, target, seq, t, length)


def _with_keyframes(start, target, seq, t, length):
    out = {}
    for n in ("q", "r", "c"):
        x = seq[n]
        shape = (1, -1) + (1,) * (x.ndim - 2)
        x = jnp.where((t == 0).reshape(shape), start[n][:, None], x)
        out[n] = jnp.where((t >= length).reshape(shape), target[n][:, None], x)
    return out


def sample(params: dict, cfg, stats: dict, start: dict, target: dict, length, keys, max_length: int) -> dict:
    """N diverse transitions: ``vmap`` of :func:`rollout` over keys (N,). Returns the rollout dict with a
    leading sample axis (N, B, ...). Jit it with ``cfg`` and ``max_length`` static.

    Latent pair search (paper, test time; ``cfg.search`` > 1, bi-directional model): each of the N samples
    draws ``cfg.search`` latent pairs (one more vmapped axis) and keeps, per keyframe pair, the one whose two
    generators meet best (smallest :func:`seam_mismatch`).  With a motion latent (``cfg.motion_latent``) each
    sample draws one from the learned prior (:func:`.motion_latent.spread_draws`, ``cfg.motion_spread``),
    shared by its candidates, so the search picks the per-step noise and keeps the sample's motion."""
    motions = None
    if cfg.motion_latent:
        motions = ML.prior_draws(params["fwd"]["motion"], cfg, stats, start, target, length,
                                 jax.vmap(lambda k: jax.random.fold_in(k, 1))(keys))
    one = lambda kk, m: rollout(params, cfg, stats, start, target, length, kk, max_length, motion=m)
    if cfg.search <= 1 or not cfg.bidirectional:
        return jax.vmap(one)(keys, motions)
    cand = jax.vmap(lambda ks, m: jax.vmap(lambda kk: one(kk, m))(ks))(
        jax.vmap(lambda kk: jax.random.split(kk, cfg.search))(keys), motions)                   # (N, C, B, ...)
    best = jnp.argmin(cand["seam"], axis=1)                                                      # (N, B)

    def pick(x):   # (N, C, B, ...) -> (N, B, ...)
        idx = best.reshape(best.shape + (1,) * (x.ndim - 3))[:, None]
        return jnp.take_along_axis(x, idx, axis=1)[:, 0]

    shared = ("valid", "h", "k")   # no batch axis: the same for every candidate
    return {n: jax.tree.map(lambda x: x[:, 0], v) if n in shared else jax.tree.map(pick, v)
            for n, v in cand.items()}


def init_params(key, cfg, num_joints: int) -> dict:
    """{"fwd": generator, "bwd": generator} with independent parameters (the forward one also holds the motion
    latent's networks, ``"motion"``, when ``cfg.motion_latent`` > 0)."""
    f = nn.ParamFactory()
    tree = {"fwd": init_generator(f, cfg, num_joints), "bwd": init_generator(f, cfg, num_joints)}
    if cfg.motion_latent:     # posterior and prior of the transition's motion latent, kept with the forward one
        tree["fwd"]["motion"] = ML.init_motion_nets(f, cfg, num_joints)
    return f.materialize(tree, key)
