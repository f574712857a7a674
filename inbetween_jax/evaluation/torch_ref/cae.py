"""PyTorch reference of one training step of the convolutional inpainting AE (``inbetween_jax.models.cae``),
for the JAX-vs-PyTorch speed rows of ``make bench`` (:mod:`inbetween_jax.evaluation.speed`).

Benchmark only: ``torch`` (``pip install torch==2.13.0``, the CPU build) is optional; this module imports
without it and :func:`available` says whether it can run.  Default threads (``torch.get_num_threads()``).

Mirrored with the same tensor shapes and convolutions: ``model.apply`` for the ``cae`` and ``vanilla`` variants
(``holden1d`` raises) with every switch the presets use -- the residual form (linear or limited-Hermite
pre-fill + mask channel, zero-initialised last conv), ``paste_known``, U-Net ``skips`` --, ``losses.weighted_l1``
(``loss.gap_weight``) and ``train.make_training``'s step: ``masks.training_mask`` drawn in the step (a gap of
mean ``mu`` or 1-3 joints removed; evaluation-matched gap lengths when ``matched``), forward, backward and
Adam (AdamW when ``train.weight_decay > 0``, global-norm clip when ``train.grad_clip > 0``) with the preset's
learning-rate schedule.  Layout NCHW: the JAX image (B, D, T, C) is (B, C, D, T) here; a conv weight
(kh, kw, Cin, Cout) is (Cout, Cin, kh, kw) (:func:`params_from_jax`).

Deliberate differences, none of which changes a tensor size or the function computed:

* The mask is drawn with torch's generator, so a step's mask differs from JAX's; :func:`loss` takes a given
  mask (the parity test, ``tests/test_torch_cae.py``, gives both frameworks the same one).  Ties at a max-pool or a leaky ReLU at exactly 0 take torch's
  sub-gradient, not JAX's: equal values almost never occur with non-zero biases.
* The stride-2 transposed conv (JAX: zero insertion + a stride-1 conv, computed phase by phase without the
  zeros, ``model.conv_upsampled``) is torch's ``conv_transpose2d`` with the flipped kernel: the same function,
  and neither side multiplies the inserted zeros.

API: :func:`available`, :func:`params_from_jax`, :func:`apply`, :func:`loss`, :func:`training_mask` and
``make_step(cfg, params, x, mu, matched=0.0, compile_backend=None, seed=0) -> step``: ``step()`` runs one
training step on the fixed clean batch ``x`` (B, D, T) and returns the loss (before the update) as a float.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

try:
    import torch
    import torch.nn.functional as F
except ImportError:  # optional dependency
    torch = None


def available() -> bool:
    """True when torch can be imported."""
    return torch is not None


# ----------------------------------------------------------------------------- parameters
def params_from_jax(params) -> dict:
    """JAX CAE parameter tree -> the same tree of torch leaf tensors (``requires_grad``); a conv's ``w``
    (kh, kw, Cin, Cout) becomes (Cout, Cin, kh, kw)."""
    if isinstance(params, dict) and set(params) == {"b", "w"}:
        w = np.asarray(params["w"], np.float32).transpose(3, 2, 0, 1)
        return {"b": torch.tensor(np.asarray(params["b"], np.float32)).requires_grad_(),
                "w": torch.tensor(np.ascontiguousarray(w)).requires_grad_()}
    if isinstance(params, dict):
        return {k: params_from_jax(v) for k, v in params.items()}
    return [params_from_jax(v) for v in params]


def leaves(tree) -> list:
    """Leaves in JAX's flattening order (sorted dict keys, list order)."""
    if isinstance(tree, dict):
        return [x for k in sorted(tree) for x in leaves(tree[k])]
    return [x for v in tree for x in leaves(v)] if isinstance(tree, list) else [tree]


# ----------------------------------------------------------------------------- the network
def _conv(layer, h):
    return F.conv2d(h, layer["w"], layer["b"], padding="same")


def _conv_upsampled(layer, h, up_h: bool):
    """SAME conv of ``layer`` over the zero-inserted h (x at even rows if ``up_h`` and even frames): a transposed
    conv with the flipped kernel, output (B, Cout, 2H or H, 2T)."""
    w = layer["w"].flip(2, 3).transpose(0, 1)                   # (Cout, Cin, kh, kw) -> (Cin, Cout, kh, kw)
    return F.conv_transpose2d(h, w, layer["b"], stride=(2 if up_h else 1, 2), padding=1,
                              output_padding=(1 if up_h else 0, 1))


def _network(params, h, cfg):
    """(B, C_in, D, T) -> (B, D, T): encoder units, mirrored decoder (model.encode / model.decode)."""
    m = cfg.model
    leak = float(m.leak)
    sizes, skips = [h.shape[2:]], []
    for unit in params["enc"]:
        pool_h = h.shape[2] >= 3
        if m.variant == "cae":
            for layer in unit:
                h = F.leaky_relu(_conv(layer, h), leak)
            skips.append(h)
            h = F.max_pool2d(h, (2 if pool_h else 1, 2), ceil_mode=True)     # = -inf padding of odd axes
        else:
            h = F.leaky_relu(_conv(unit[0], h), leak)[:, :, ::2 if pool_h else 1, ::2]
        sizes.append(h.shape[2:])
    n = len(params["dec"])
    for u, unit in enumerate(params["dec"]):
        th, tw = sizes[n - 1 - u]
        up_h = th > h.shape[2]
        for r, layer in enumerate(unit):
            h = _conv_upsampled(layer, h, up_h) if r == 0 else _conv(layer, h)
            if r == 0:
                h = h[:, :, :th, :tw]
                if m.skips:
                    h = torch.cat([F.leaky_relu(h, leak), skips[n - 1 - u]], 1)
                    continue
            if not (u == n - 1 and r == len(unit) - 1):
                h = F.leaky_relu(h, leak)
    return h[:, 0]


def _neighbours(x, known):
    """Per entry: index of the last known entry <= t and of the first known entry >= t (T where none)."""
    t_len = x.shape[-1]
    t = torch.arange(t_len).expand_as(x)
    prev = torch.cummax(torch.where(known, t, -1), -1).values
    nxt = torch.flip(torch.cummin(torch.flip(torch.where(known, t, t_len), [-1]), -1).values, [-1])
    return t, prev, nxt


def prefill(x, mask, fill: str = "linear", limit: float = 3.0):
    """masks.linear_prefill / baselines.hermite_fill (order 2, limiter ``limit``) in torch; x, mask (B, D, T)."""
    known = mask > 0.5
    t_len = x.shape[-1]
    t, prev, nxt = _neighbours(x, known)
    has_prev, has_next = prev >= 0, nxt < t_len

    def at(idx):
        i = idx.clamp(0, t_len - 1)
        return torch.gather(x, -1, i), (idx >= 0) & (idx < t_len) & torch.gather(known, -1, i)

    x0, _ = at(prev)
    x1, _ = at(nxt)
    span = (nxt - prev).clamp(min=1).to(x.dtype)
    if fill == "linear":
        inner = x0 + ((t - prev) / span).to(x.dtype) * (x1 - x0)
    elif fill == "hermite":
        d = (x1 - x0) / span
        xa1, ka1 = at(prev - 1)
        xb1, kb1 = at(nxt + 1)
        xa2, ka2 = at(prev - 2)
        xb2, kb2 = at(nxt + 2)
        m0 = torch.where(ka1 & ka2, (3.0 * x0 - 4.0 * xa1 + xa2) / 2.0, torch.where(ka1, x0 - xa1, d))
        m1 = torch.where(kb1 & kb2, (-3.0 * x1 + 4.0 * xb1 - xb2) / 2.0, torch.where(kb1, xb1 - x1, d))
        cap = float(limit) * d.abs()
        m0 = torch.where(m0 * d > 0, torch.sign(m0) * torch.minimum(m0.abs(), cap), torch.zeros_like(m0))
        m1 = torch.where(m1 * d > 0, torch.sign(m1) * torch.minimum(m1.abs(), cap), torch.zeros_like(m1))
        s = ((t - prev) / span).to(x.dtype)
        s2, s3 = s * s, s * s * s
        inner = ((2.0 * s3 - 3.0 * s2 + 1.0) * x0 + (-2.0 * s3 + 3.0 * s2) * x1
                 + span * ((s3 - 2.0 * s2 + s) * m0 + (s3 - s2) * m1))
    else:
        raise ValueError(f"unknown model.fill {fill!r}")
    filled = torch.where(has_prev & has_next, inner, torch.where(has_prev, x0, torch.where(has_next, x1, 0.0)))
    return torch.where(known, x, filled)


def apply(params, x, cfg, mask=None):
    """model.apply: x (B, D, T) the masked input, mask (B, D, T) 1 = known -> (B, D, T)."""
    m = cfg.model
    if m.variant == "holden1d":
        raise NotImplementedError("the torch reference implements the cae and vanilla variants")
    if mask is None and (m.residual or m.paste_known):
        mask = torch.ones_like(x)
    if m.residual:
        base = prefill(x, mask, m.fill)
        out = base + _network(params, torch.stack([base, mask], 1), cfg)
    else:
        out = _network(params, x[:, None], cfg)
    return torch.where(mask > 0.5, x, out) if m.paste_known else out


def loss(params, x, mask, cfg):
    """losses.weighted_l1 of ``apply(params, x * mask, cfg, mask)`` against the clean x (B, D, T): a scalar."""
    err = (apply(params, x * mask, cfg, mask) - x).abs()
    g = float(cfg.loss.gap_weight)
    if g == 1.0:
        return err.mean()
    w = 1.0 + (g - 1.0) * (1.0 - mask)
    return (w * err).sum() / w.sum()


# ----------------------------------------------------------------------------- the train step
def training_mask(gen, batch, num_joints, length, mu, k, matched=0.0):
    """masks.training_mask with torch's generator (k: cfg.data.mask): (B, D, T), 1 = known."""
    rand = lambda *s: torch.rand(s, generator=gen)                             # noqa: E731
    if matched > 0.5:
        c = torch.tensor(k.matched_frames, dtype=torch.float32)[torch.randint(len(k.matched_frames), (batch,),
                                                                              generator=gen)]
        lam = torch.round(c * (1.0 + k.matched_spread * (2.0 * rand(batch) - 1.0)))
    else:
        lam = torch.round(mu + k.sigma * torch.randn(batch, generator=gen))
    lam = lam.clamp(1, length - 1)
    tau = torch.floor(rand(batch) * (length - lam + 1))
    t = torch.arange(length)[None]
    cols = 1.0 - ((t >= tau[:, None]) & (t < (tau + lam)[:, None])).float()               # (B, T)
    n = torch.randint(1, k.max_joints + 1, (batch, 1), generator=gen)
    score = rand(batch, num_joints)
    score[:, 0] = 2.0                                                                    # the root ranks last
    joints = (score.argsort(1).argsort(1) >= n).float()                                  # (B, J)
    rows = torch.cat([joints.repeat_interleave(3, 1), torch.ones(batch, 3)], 1)[:, :, None].expand(-1, -1, length)
    use_rows = rand(batch, 1, 1) < k.p_joint
    return torch.where(use_rows, rows, cols[:, None, :].expand_as(rows)).contiguous()


def learning_rate(tc, step: int) -> float:
    """train.optim.learning_rate at ``step`` (optax's constant / warm-up + cosine schedules)."""
    if tc.lr_schedule == "constant":
        return tc.lr * min(1.0, step / tc.warmup_steps) if tc.warmup_steps > 0 else tc.lr
    warm, total = max(tc.warmup_steps, 1), max(tc.num_steps, tc.warmup_steps + 1)
    if step < warm:
        init = 0.0 if tc.warmup_steps > 0 else tc.lr
        return init + (tc.lr - init) * step / warm
    frac = min(step - warm, total - warm) / (total - warm)
    return tc.lr * (tc.lr_final + (1.0 - tc.lr_final) * 0.5 * (1.0 + math.cos(math.pi * frac)))


def make_step(cfg, params, x, mu, matched=0.0, compile_backend=None, seed=0) -> Callable[[], float]:
    """One-training-step closure on the fixed clean batch x ((B, D, T) float array).

    params: a JAX parameter tree (copied, :func:`params_from_jax`); mu / matched: the batch's mean gap length
    and matched flag (train.make_training's batch); compile_backend: None (eager) or a ``torch.compile``
    backend ("inductor", "aot_eager"), which compiles the loss (forward and backward) -- the mask draw and
    Adam stay eager.  Compilation happens in the first call.  The closure's attribute ``backend`` names it.
    """
    tc, k = cfg.train, cfg.data.mask
    tp = params_from_jax(params)
    ps = leaves(tp)
    opt = (torch.optim.AdamW(ps, lr=tc.lr, betas=(tc.b1, tc.b2), eps=1e-8, weight_decay=tc.weight_decay)
           if tc.weight_decay > 0 else torch.optim.Adam(ps, lr=tc.lr, betas=(tc.b1, tc.b2), eps=1e-8))
    xt = torch.tensor(np.asarray(x, np.float32))
    b, d, length = xt.shape
    gen = torch.Generator().manual_seed(seed)
    fn = lambda p, xx, mm: loss(p, xx, mm, cfg)                                # noqa: E731
    if compile_backend is not None:
        fn = torch.compile(fn, backend=compile_backend)
    count = [0]

    def step() -> float:
        mask = training_mask(gen, b, (d - 3) // 3, length, float(mu), k, float(matched))
        value = fn(tp, xt, mask)
        opt.zero_grad(set_to_none=True)
        value.backward()
        if tc.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(ps, tc.grad_clip)
        for group in opt.param_groups:
            group["lr"] = learning_rate(tc, count[0])
        opt.step()
        count[0] += 1
        return float(value.detach())

    step.backend = compile_backend or "eager"
    return step
