"""PyTorch-eager reference of one S-CVAE training step, for a JAX-vs-PyTorch speed benchmark on one CPU.

Benchmark only: ``torch`` (``pip install .[bench]``, the torch 2.13.0 CPU build) is optional; this module
imports without it and :func:`available` says whether it can run.  Eager mode, or ``make_step(...,
compile_backend=...)``: the rollout's step function under ``torch.compile``, called in the Python loop, and the
generator loss around the rollout compiled too.  Until 2026-12-07 the whole generator loss went to
``torch.compile``: the latent noise's ``torch.Generator`` broke the graph inside every step, and after 8
recompiles (a new graph per step's numbers) dynamo ran the step eagerly, so "compiled" was mostly eager.  Now
the noise is drawn outside and the per-step numbers are 0-d tensors: one step graph (4 variants: which inputs
carry gradients) serves all steps.  The whole unrolled rollout as one graph did not compile with inductor in
10 min.  No TorchScript, default threads:
``torch.get_num_threads()`` is 2 (one per core) on the 2-core machine used for the timings.  With other
processes busy on those cores, 2 threads ran the paper-size step 4-8x slower than 1 thread
(``OMP_NUM_THREADS=1``): time on an idle CPU, or report the thread count with the numbers.

Mirrored with the same matrix shapes, step count, batch and matmuls per step: ``models.scvae.model.rollout``
(forward and backward generators with separate parameters alternating over ``max_length // 2 + K`` steps,
bi-directional aligning, Eq. 2 latent-interpolation gamma, two-stage encoder through the shared LSTM from the
same carry, decoder LSTM + phase-gated blended-weight MoE, the phase network without gradient) and
``model.stitch``; ``models.scvae.train.generator_loss`` (state / quaternion / velocity / contact terms, KL, FK
positions via one FK call for both generators, stitching loss, teacher-forced phase loss, generator LSGAN term
through the 10- and 2-frame discriminators with detached weights); ``train.make_train_step`` (backward,
global-norm clip + AdamW, then the discriminator loss on the detached stitched output, backward, clip + AdamW).

Deliberate differences, none of which changes a matrix size:

* Init and noise come from torch, so runs differ numerically from JAX; with JAX's weights loaded and zero
  latent noise, three full training steps reproduce JAX's losses (tests/test_torch_reference.py, slow).
* Per-step scalars (gamma, time to arrival, the aligning switch) are Python numbers; the eager loop takes the
  ``where(aligned, ...)`` branch on the host instead of selecting between two computed frames.
* The encoder's two LSTM passes from the same carry compute ``h @ W_h`` once.  The JAX source writes it
  twice, but XLA's common-subexpression elimination merges the identical dots (compiled HLO: 3 dots in the
  forward pass, not 4), so this matches what XLA executes.  Likewise FK skips the global rotations of leaf
  joints and the generator loss does not score the real windows: dead code that XLA removes.
* Only the bi-directional model (``model.bidirectional=False`` raises); the other ablation switches are honoured.

API: :func:`available`, :func:`param_count`, :func:`init_params` and
``make_step(cfg, num_joints, parents, stats, batch, length, seed=0) -> step``; ``step()`` runs one full
training step on the fixed batch and returns the generator loss (before the update) as a Python float.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

try:
    import torch
    import torch.nn.functional as F
except ImportError:  # optional dependency
    torch = None

PHASE_DIM = 4


def available() -> bool:
    """True when torch can be imported."""
    return torch is not None


# ----------------------------------------------------------------------------- parameters
# Declared as trees of (shape, lim) leaves: U(-lim, lim), or lim None for an LSTM bias with forget-gate 1.
def _mlp_p(sizes):
    return [{"w": ((a, b), a ** -0.5), "b": ((b,), a ** -0.5)} for a, b in zip(sizes[:-1], sizes[1:])]


def _lstm_p(d_in, hid):
    return {"wx": ((d_in, 4 * hid), hid ** -0.5), "wh": ((hid, 4 * hid), hid ** -0.5), "b": ((4 * hid,), None)}


def _generator_p(m, num_joints: int) -> dict:
    """Same tree and shapes as :func:`inbetween_jax.models.scvae.model.init_generator` (m: ModelConfig)."""
    st, e, o, lat2 = 4 * num_joints + 7, m.enc_hidden, m.enc_out, 2 * m.latent_dim
    enc = {"state": _mlp_p((st, e, e, o)), "offset": _mlp_p((st - 4, e, e, o)), "target": _mlp_p((st - 7, e, e, o)),
           "head_cur": _mlp_p((m.lstm_hidden, m.head_hidden, lat2)),
           "head_tgt": _mlp_p((m.lstm_hidden, m.head_hidden, lat2))}
    if m.encoder_lstm:
        enc["lstm"] = _lstm_p(3 * o, m.lstm_hidden)
    else:
        enc["mlp"] = _mlp_p((3 * o, m.lstm_hidden))
    sizes, n_exp = (m.dec_lstm_hidden,) + tuple(m.expert_hidden) + (st,), m.num_experts if m.phase_moe else 1
    dec = {"lstm": _lstm_p(m.latent_dim + 2 * o, m.dec_lstm_hidden),   # experts: W (E, in, out), b (E, out)
           "experts": [{"w": ((n_exp, a, b), a ** -0.5), "b": ((n_exp, b), a ** -0.5)}
                       for a, b in zip(sizes[:-1], sizes[1:])]}
    if m.phase_moe:
        dec["gating"] = _mlp_p((PHASE_DIM,) + tuple(m.gating_hidden) + (m.num_experts,))
    return {"enc": enc, "dec": dec, "phase": _mlp_p((st + PHASE_DIM, m.phase_hidden, m.phase_hidden, 4))}


def leaves(tree) -> list:
    """Leaves of a nested dict / list (tuples are leaves), in a fixed order."""
    if isinstance(tree, dict):
        return [x for k in sorted(tree) for x in leaves(tree[k])]
    return [x for v in tree for x in leaves(v)] if isinstance(tree, list) else [tree]


def param_count(cfg, num_joints: int) -> int:
    """Generator parameters (forward + backward); equals the JAX ``model.init_params`` count. No torch needed."""
    return 2 * sum(int(np.prod(shape)) for shape, _ in leaves(_generator_p(cfg.model, num_joints)))


def _draw(tree, gen):
    """Replace every (shape, lim) leaf by a float32 tensor with ``requires_grad``."""
    if isinstance(tree, (dict, list)):
        return {k: _draw(v, gen) for k, v in tree.items()} if isinstance(tree, dict) else [_draw(v, gen) for v in tree]
    shape, lim = tree
    if lim is None:
        x = torch.zeros(shape)
        x[shape[0] // 4:shape[0] // 2] = 1.0       # gates (i, f, g, o)
    else:
        x = (torch.rand(shape, generator=gen) * 2.0 - 1.0) * lim
    return x.requires_grad_()


def init_params(mcfg, num_joints: int, seed: int = 0) -> dict:
    """{"gen": {"fwd", "bwd"} generators, "disc": {"long", "short"} discriminators (window*D -> hidden -> 1)}."""
    feat, hid = 4 * num_joints + 7, tuple(mcfg.disc_hidden)
    tree = {"gen": {"fwd": _generator_p(mcfg, num_joints), "bwd": _generator_p(mcfg, num_joints)},
            "disc": {"long": _mlp_p((mcfg.disc_long * feat,) + hid + (1,)),
                     "short": _mlp_p((mcfg.disc_short * feat,) + hid + (1,))}}
    return _draw(tree, torch.Generator().manual_seed(seed))


# ----------------------------------------------------------------------------- building blocks
def _mlp(layers, x, alpha=None):
    """x (..., d_in) -> (..., d_out); ELU between layers (layers.mlp).  With alpha (B, E): the blended-weight
    mixture of experts (layers.moe), x (B, d_in), layers W (E, d_in, d_out), b (E, d_out)."""
    for i, l in enumerate(layers):
        if alpha is None:
            x = F.linear(x, l["w"].t(), l["b"])
        else:
            x = torch.einsum("be,beo->bo", alpha, torch.einsum("bi,eio->beo", x, l["w"]) + l["b"][None])
        if i < len(layers) - 1:
            x = F.elu(x)
    return x


def _lstm(p, carry, x, hh=None):
    """One LSTM step, gates (i, f, g, o); hh = h @ W_h when already computed. Returns ((h, c), h), each (B, H)."""
    h, c = carry
    gates = torch.addmm(p["b"], x, p["wx"]) + (h @ p["wh"] if hh is None else hh)
    i, f, g, o = gates.chunk(4, -1)
    c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
    h = torch.sigmoid(o) * torch.tanh(c)
    return (h, c), h


def _tta_emb(tta, dim: int, basis: float):
    """(1, dim) sinusoidal time-to-arrival embedding (Eq. 11-12); tta a number or a 0-d tensor."""
    i = torch.arange(dim // 2, dtype=torch.float32)
    ang = torch.as_tensor(tta, dtype=torch.float32) / basis ** (2.0 * i / dim)
    return torch.stack([torch.sin(ang), torch.cos(ang)], -1).reshape(1, dim)


def _scalar(x):
    """A per-step number as a 0-d float32 tensor: one compiled step serves every step (a Python number would be
    a constant of the compiled graph, recompiled for each value)."""
    return torch.tensor(float(x), dtype=torch.float32)


def _qnorm(q):
    return q / torch.sqrt(torch.clamp((q * q).sum(-1, keepdim=True), min=1e-16))


def _qmul(a, b):
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                        aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], -1)


def _qrot(q, v):
    u = q[..., 1:]
    t = 2.0 * torch.linalg.cross(u, v, dim=-1)
    return v + q[..., :1] * t + torch.linalg.cross(u, t, dim=-1)


def _fk_positions(q, r, offsets, parents):
    """q (..., J, 4), r (..., 3), offsets (J, 3) -> global positions (..., J, 3)."""
    needed = set(parents)
    gq, gp = {0: q[..., 0, :]}, [r]
    for j in range(1, len(parents)):
        p = parents[j]
        gp.append(_qrot(gq[p], offsets[j].expand_as(r)) + gp[p])
        if j in needed:
            gq[j] = _qmul(gq[p], q[..., j, :])
    return torch.stack(gp, -2)


def _align_sign(q, ref):
    return torch.where((q * ref).sum(-1, keepdim=True) < 0, -q, q)


def _velocity(r):
    """(B, T, 3) -> (B, T, 3) with v_0 = 0."""
    return torch.cat([torch.zeros_like(r[:, :1]), r[:, 1:] - r[:, :-1]], 1)


def _masked_mean(x, mask):
    mask = mask.to(x.dtype).expand_as(x)
    return (x * mask).sum() / torch.clamp(mask.sum(), min=1.0)


def _rev(fr):
    return dict(fr, v=-fr["v"])


# ----------------------------------------------------------------------------- the model
class _Model:
    """Rollout and losses on fixed config / stats; all shapes as in the JAX code (B batch, J joints)."""

    def __init__(self, cfg, num_joints, parents, stats):
        self.m, self.lc, self.parents = cfg.model, cfg.loss, tuple(int(p) for p in parents)
        self.v_std, self.off_std, self.offsets = (torch.as_tensor(np.asarray(stats[n], np.float32))
                                                  for n in ("v_std", "off_std", "offsets"))
        self.pos_unit = float(stats["pos_unit"])
        self.emb0 = _tta_emb(0.0, self.m.enc_out, self.m.tta_basis)
        self.step_fn = self.gen_step           # make_step(compile_backend=...) puts the compiled step here

    def state_feat(self, f):
        """(B, 4J+7)."""
        return torch.cat([f["q"].reshape(f["q"].shape[0], -1), f["v"] / self.v_std, f["c"]], -1)

    def offset_feat(self, cur, tgt_q, tgt_r):
        """(B, 3+4J): scaled root offset and element-wise quaternion offset to the target."""
        b = cur["q"].shape[0]
        return torch.cat([(tgt_r - cur["r"]) / self.off_std, (tgt_q - cur["q"]).reshape(b, -1)], -1)

    def phase_step(self, p, frame):
        """phase_{t+1} = phase_t + net([state_t, phase_t]) (B, 4)."""
        return frame["phase"] + _mlp(p, torch.cat([self.state_feat(frame), frame["phase"]], -1))

    def gen_step(self, p, carry, cur, tgt, tta, gamma, eps):
        """f_{i+1} = G(f_i | f_target) (encoder Fig. 3, decoder Fig. 5).  carry = (encoder (h, c), decoder (h, c)),
        each (B, H); frames hold q (B, J, 4), r / v (B, 3), c (B, 4), phase (B, 4); eps (B, Z): the latent's
        standard normal noise.  Returns (carry, frame, kl (B,))."""
        m, pe, pd = self.m, p["enc"], p["dec"]
        b, j = cur["q"].shape[:2]
        tgt_q = _align_sign(tgt["q"], cur["q"])
        tgt_state = dict(tgt, q=tgt_q)
        emb = _tta_emb(torch.clamp(tta, max=float(m.tta_max)), m.enc_out, m.tta_basis)
        t_raw = _mlp(pe["target"], tgt_q.reshape(b, -1))
        s1 = _mlp(pe["state"], self.state_feat(cur)) + emb                     # stage 1: current frame
        t1 = t_raw + emb
        x1 = torch.cat([s1, _mlp(pe["offset"], self.offset_feat(cur, tgt_q, tgt["r"])) + emb, t1], -1)
        x2 = torch.cat([_mlp(pe["state"], self.state_feat(tgt_state)) + self.emb0,   # stage 2: target, tta 0
                        _mlp(pe["offset"], self.offset_feat(tgt_state, tgt_q, tgt["r"])) + self.emb0,
                        t_raw + self.emb0], -1)
        if m.encoder_lstm:
            hh = carry[0][0] @ pe["lstm"]["wh"]                 # shared by both stages (XLA CSEs the duplicate)
            enc_c, h1 = _lstm(pe["lstm"], carry[0], x1, hh)
            _, h2 = _lstm(pe["lstm"], carry[0], x2, hh)
        else:
            enc_c, h1, h2 = carry[0], F.elu(_mlp(pe["mlp"], x1)), F.elu(_mlp(pe["mlp"], x2))
        mu_c, lv_c = _mlp(pe["head_cur"], h1).chunk(2, -1)
        mu_t, lv_t = _mlp(pe["head_tgt"], h2).chunk(2, -1)
        mu = (1.0 - gamma) * mu_c + gamma * mu_t
        lv_c, lv_t = lv_c.clamp(-10.0, 5.0), lv_t.clamp(-10.0, 5.0)
        sigma = (1.0 - gamma) * torch.exp(0.5 * lv_c) + gamma * torch.exp(0.5 * lv_t)
        z = mu + sigma * eps
        kl = 0.5 * (mu ** 2 + sigma ** 2 - 1.0 - 2.0 * torch.log(sigma + 1e-8)).sum(-1)
        dec_c, h = _lstm(pd["lstm"], carry[1], torch.cat([z, s1, t1], -1))     # decoder input [z, s emb, t emb]
        alpha = (torch.softmax(_mlp(pd["gating"], cur["phase"].detach()), -1) if m.phase_moe else torch.ones(b, 1))
        out = _mlp(pd["experts"], h, alpha)
        v = out[:, 4 * j:4 * j + 3] * self.v_std
        nxt = {"q": _qnorm(cur["q"] + out[:, :4 * j].reshape(b, j, 4)), "r": cur["r"] + v, "v": v,
               "c": torch.sigmoid(out[:, 4 * j + 3:])}
        with torch.no_grad():                     # the phase net gets no gradient from the rollout (as in JAX)
            nxt["phase"] = self.phase_step(p["phase"], cur)
        return (enc_c, dec_c), nxt, kl

    def rollout(self, params, start, target, length: int, steps: int, eps) -> dict:
        """Bi-directional aligned rollout of ``steps`` steps per direction; eps (steps, 2, B, Z): the latent noise of
        each step, forward then backward generator.  Frames (B, S, ...), kl (B, S)."""
        m, b = self.m, start["q"].shape[0]
        h = length // 2
        k = min(max(m.buffer_k, 1), max(h - 1, 1))
        zv, zp = torch.zeros_like(start["r"]), torch.zeros(b, PHASE_DIM)
        s0, t0 = dict(start, v=zv), dict(target, v=zv)
        with torch.no_grad():
            s0["phase"] = self.phase_step(params["fwd"]["phase"], dict(s0, phase=zp))
            t0["phase"] = self.phase_step(params["bwd"]["phase"], dict(t0, phase=zp))
        zc = lambda n: (torch.zeros(b, n), torch.zeros(b, n))
        cf = cb = (zc(m.lstm_hidden), zc(m.dec_lstm_hidden))
        cur_f, cur_b = s0, _rev(t0)
        fwd, bwd, kl_f, kl_b = [], [], [], []
        for n in range(steps):
            aligned = m.aligning and n < h
            gam = (n / max(h, 1) if n < h else n / (h + k)) if m.latent_interp else 0.0
            tgt_f, tta_f = (_rev(cur_b), length - 2 * n) if aligned else (t0, length - n)
            cf, nxt_f, kf = self.step_fn(params["fwd"], cf, cur_f, tgt_f, _scalar(tta_f), _scalar(gam), eps[n, 0])
            tgt_b, tta_b = (_rev(nxt_f), length - 2 * n - 1) if aligned else (_rev(s0), length - n)
            cb, nxt_b, kb = self.step_fn(params["bwd"], cb, cur_b, tgt_b, _scalar(tta_b), _scalar(gam), eps[n, 1])
            cur_f, cur_b = nxt_f, nxt_b
            fwd.append(nxt_f), bwd.append(nxt_b), kl_f.append(kf), kl_b.append(kb)
        stack = lambda frames: {n: torch.stack([f[n] for f in frames], 1) for n in ("q", "r", "v", "c")}
        s = torch.arange(steps)
        return {"fwd": stack(fwd), "bwd": stack(bwd), "kl_fwd": torch.stack(kl_f, 1), "kl_bwd": torch.stack(kl_b, 1),
                "valid": (s < h + k) & (s + 1 <= length - 1), "h": h, "k": k}

    def stitch(self, start, target, fwd, bwd, length, h, k, t1):
        """Blend over the 2K buffer; keyframes at t = 0 and t >= length. q (B, t1, J, 4), r (B, t1, 3), c (B, t1, 4)."""
        s = fwd["q"].shape[1]
        t = torch.arange(t1)
        fi, bi = (t - 1).clamp(0, s - 1), (length - 1 - t).clamp(0, s - 1)
        w = ((t - (h - k)).float() / (2 * k + 1)).clamp(0.0, 1.0)
        fq = fwd["q"][:, fi]
        bq = _align_sign(bwd["q"][:, bi], fq)
        wq, wr = w[None, :, None, None], w[None, :, None]
        out = {"q": _qnorm((1 - wq) * fq + wq * bq)}
        for n in ("r", "c"):
            out[n] = (1 - wr) * fwd[n][:, fi] + wr * bwd[n][:, bi]
        for n, x in out.items():
            shape = (1, -1) + (1,) * (x.ndim - 2)
            x = torch.where((t == 0).reshape(shape), start[n][:, None], x)
            out[n] = torch.where((t >= length).reshape(shape), target[n][:, None], x)
        return out

    # ------------------------------------------------------------------------- losses
    def direction(self, pred, pos, kl, valid, gt):
        """(state, kl, fk) scalars of one generator (as models.scvae.losses.direction_losses)."""
        s, lc = pred["q"].shape[1], self.lc
        quat = (pred["q"] - gt["q"][:, 1:s + 1]).abs().mean((-1, -2))
        vel = ((pred["v"] - _velocity(gt["r"])[:, 1:s + 1]).abs() / self.v_std).mean(-1)
        con = (pred["c"] - gt["c"][:, 1:s + 1]).abs().mean(-1)
        state = _masked_mean(lc.beta_quat * quat + lc.beta_vel * vel + lc.beta_contact * con, valid)
        fk = _masked_mean((pos - gt["p"][:, 1:s + 1]).abs().mean((-1, -2)) / self.pos_unit, valid)
        return state, _masked_mean(kl, valid), fk

    def stitch_loss(self, pos_f, pos_b, length, h, k):
        s = pos_f.shape[1]
        t = torch.arange(1, s + 1)
        pb = pos_b[:, (length - 1 - t).clamp(0, s - 1)]
        mask = (t >= h - k + 1) & (t <= h + k)
        return _masked_mean((pos_f - pb).abs().mean((-1, -2)), mask) / self.pos_unit

    def phase_loss(self, p, gt, length):
        """Teacher-forced L1 of the phase net over all B*T1 frames plus its keyframe estimate."""
        b, t = gt["q"].shape[:2]
        frames = {"q": gt["q"], "v": _velocity(gt["r"]), "c": gt["c"], "phase": gt["phase"]}
        nxt = self.phase_step(p, {n: x.reshape((b * t,) + x.shape[2:]) for n, x in frames.items()}).reshape(b, t, -1)
        step_err = (nxt[:, :-1] - gt["phase"][:, 1:]).abs().mean(-1)
        first = {"q": gt["q"][:, 0], "v": torch.zeros_like(gt["r"][:, 0]), "c": gt["c"][:, 0],
                 "phase": torch.zeros_like(gt["phase"][:, 0])}
        init_err = (self.phase_step(p, first) - gt["phase"][:, 0]).abs().mean()
        return _masked_mean(step_err, torch.arange(t - 1) < length) + init_err

    def disc_feat(self, seq):
        """(B, T, 4J+7) per-frame discriminator input."""
        b, t = seq["q"].shape[:2]
        return torch.cat([seq["q"].reshape(b, t, -1), _velocity(seq["r"]) / self.v_std, seq["c"]], -1)

    def lsgan(self, dparams, fake, real, length):
        """Eq. 8-9 summed over the long / short discriminators on every sliding window inside frames 0..length:
        L_G when ``real`` is None, else L_D.  fake / real: (B, T, D) features."""
        loss = 0.0
        for name, w in (("long", self.m.disc_long), ("short", self.m.disc_short)):
            n = fake.shape[1] - w + 1
            mask = torch.arange(n) + w - 1 <= length
            score = lambda x: _mlp(dparams[name], torch.cat([x[:, i:i + n] for i in range(w)], -1))[..., 0]
            f = score(fake)                                                     # (B, n)
            if real is None:
                loss = loss + 0.5 * _masked_mean((f - 1.0) ** 2, mask)
            else:
                loss = loss + 0.5 * _masked_mean((score(real) - 1.0) ** 2, mask) + 0.5 * _masked_mean(f ** 2, mask)
        return loss


# ----------------------------------------------------------------------------- the train step
def make_step(cfg, num_joints: int, parents, stats: dict, batch: dict, length: int,
              seed: int = 0, compile_backend: str | None = None) -> Callable[[], float]:
    """One-training-step closure on a fixed batch.

    cfg: ``inbetween_jax.models.scvae.config.Config``; stats: ``features.compute_stats`` (v_std (3,), off_std (3,),
    pos_unit (), offsets (J, 3)); batch: ``models.scvae.train.make_batch`` output (q (B, T1, J, 4), r (B, T1, 3),
    c (B, T1, 4), phase_f / phase_b (B, T1, 4), p (B, T1, J, 3)); length: L = frames between keyframes
    (T1 - 1 = max_length fixes the step count).  The closure returns the generator loss (before the update).
    compile_backend: None (eager) or a ``torch.compile`` backend ("inductor", "aot_eager") for the rollout's step
    and the generator loss around the rollout (forward and backward; compiled in the first calls); the rollout's
    loop, the optimisers and the discriminator stay eager.
    """
    m, lc, tc = cfg.model, cfg.loss, cfg.train
    if not m.bidirectional:
        raise NotImplementedError("the torch reference implements the bi-directional S-CVAE only")
    length = int(length)
    if "length" in batch and int(batch["length"]) != length:
        raise ValueError(f"length={length} but batch['length']={int(batch['length'])}")
    model = _Model(cfg, num_joints, parents, stats)
    params = init_params(m, num_joints, seed)
    gen_leaves, disc_leaves = leaves(params["gen"]), leaves(params["disc"])
    adamw = lambda ps: torch.optim.AdamW(ps, lr=tc.lr, betas=(tc.b1, tc.b2), eps=1e-8, weight_decay=tc.weight_decay)
    opt_g, opt_d = adamw(gen_leaves), adamw(disc_leaves)
    bt = {n: torch.as_tensor(np.asarray(batch[n], np.float32)) for n in ("q", "r", "c", "phase_f", "phase_b", "p")}
    t1 = bt["q"].shape[1]
    if not 1 <= length < t1:
        raise ValueError(f"length={length} needs 1 <= length <= max_length={t1 - 1}")
    steps = (t1 - 1) // 2 + m.buffer_k                      # model.num_scan_steps(cfg.model, max_length)
    noise = torch.Generator().manual_seed(seed + 1)
    eps_shape = (steps, 2, bt["q"].shape[0], m.latent_dim)

    def generator_loss(eps):
        rev = (length - torch.arange(t1)).clamp(0, t1 - 1)
        start = {n: bt[n][:, 0] for n in ("q", "r", "c")}
        target = {n: bt[n][:, length] for n in ("q", "r", "c")}
        gt_f = {"q": bt["q"], "r": bt["r"], "c": bt["c"], "phase": bt["phase_f"], "p": bt["p"]}
        gt_b = {"q": bt["q"][:, rev], "r": bt["r"][:, rev], "c": bt["c"][:, rev], "phase": bt["phase_b"][:, rev],
                "p": bt["p"][:, rev]}
        res = model.rollout(params["gen"], start, target, length, steps, eps)
        fwd, bwd, h, k = res["fwd"], res["bwd"], res["h"], res["k"]
        out = model.stitch(start, target, fwd, bwd, length, h, k, t1)
        both = _fk_positions(torch.cat([fwd["q"], bwd["q"]]), torch.cat([fwd["r"], bwd["r"]]), model.offsets,
                             model.parents)
        pos_f, pos_b = both.chunk(2)
        sf, kf, ff = model.direction(fwd, pos_f, res["kl_fwd"], res["valid"], gt_f)
        sb, kb, fb = model.direction(bwd, pos_b, res["kl_bwd"], res["valid"], gt_b)
        ph = 0.5 * (model.phase_loss(params["gen"]["fwd"]["phase"], gt_f, length)
                    + model.phase_loss(params["gen"]["bwd"]["phase"], gt_b, length))
        loss = 0.5 * (sf + sb) + lc.alpha_kl * 0.5 * (kf + kb) + lc.alpha_fk * 0.5 * (ff + fb) + lc.phase * ph
        stitch = model.stitch_loss(pos_f, pos_b, length, h, k)
        if m.stitch_loss:
            loss = loss + lc.alpha_stitch * stitch
        if m.discriminators:
            frozen = {name: [{n: x.detach() for n, x in layer.items()} for layer in ls]
                      for name, ls in params["disc"].items()}
            loss = loss + lc.alpha_g * model.lsgan(frozen, model.disc_feat(out), None, length)
        return loss, out

    gen_loss = generator_loss
    if compile_backend is not None:
        # the rollout's step compiled once and called in a Python loop, as a user compiles an autoregressive model
        # (the whole unrolled rollout as one graph took inductor more than 10 min); the loss around it compiled too.
        # Dynamo keeps one cache per function for every model built in the process (4 graphs each: widths and
        # backends add up), and past its recompile limit (8) it would run the step eagerly.
        torch._dynamo.config.recompile_limit = max(torch._dynamo.config.recompile_limit, 64)
        # (dynamic=False: another width's shapes are new graphs, not symbolic shapes, which compiled slowly here)
        model.step_fn = torch.compile(model.gen_step, backend=compile_backend, dynamic=False)
        model.rollout = torch.compiler.disable(model.rollout)
        gen_loss = torch.compile(generator_loss, backend=compile_backend, dynamic=False)

    def step() -> float:
        loss, out = gen_loss(torch.randn(eps_shape, generator=noise))     # drawn outside: no graph break
        opt_g.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(gen_leaves, tc.grad_clip)
        opt_g.step()
        if m.discriminators:
            fake = model.disc_feat({n: x.detach() for n, x in out.items()})
            real = model.disc_feat({n: bt[n] for n in ("q", "r", "c")})
            ld = model.lsgan(params["disc"], fake, real, length)
            opt_d.zero_grad(set_to_none=True)
            (lc.alpha_d * ld).backward()
            torch.nn.utils.clip_grad_norm_(disc_leaves, tc.grad_clip)
            opt_d.step()
        return float(loss.detach())

    return step

