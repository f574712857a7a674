"""Convolutional inpainting autoencoder for motion infilling (Kaufmann et al., "Convolutional Autoencoders
for Human Motion Infilling", 3DV 2020) and its two network baselines.

A motion clip is an "image" ``x`` of shape ``(B, D, T)``: D feature rows (root-relative joint positions,
root velocities; see :mod:`inbetween_jax.models.cae.features`) by T frames.  Every model maps
``(B, D, T) -> (B, D, T)`` for any D >= 1 and T >= 1 (fully convolutional).

Parameters are plain nested dicts / lists of arrays (:func:`init_params`) and :func:`apply` is a pure function
``apply(params, x, cfg)`` (``cfg``: the :class:`~inbetween_jax.models.cae.config.Config`, used as static
Python values).  A conv layer is ``{"b": (Cout,), "w": (kh, kw, Cin, Cout)}``; the CAE / Vanilla AE hold
``{"dec": [unit, ...], "enc": [unit, ...]}`` with a unit a list of one or two convs, the Holden AE
``{"dec": conv, "enc": conv}``.

Variants (``cfg.model.variant``):

* ``"cae"`` -- the paper's model (Fig. 4): 5 encoding units of two 3x3 convs + leaky ReLU followed by a
  2x2 max-pool; a mirrored, weight-decoupled decoder whose units are a stride-2 3x3 transposed conv then a
  3x3 conv (leaky ReLU after each, none on the very last output).  Channels (32, 64, 128, 256, 256) give a
  3 x 8 x 256 latent for a 69 x 240 input, as in the paper.
* ``"vanilla"`` -- the paper's "Vanilla AE": one strided 3x3 conv per encoding unit and one strided 3x3
  transposed conv per decoding unit (same channels).
* ``"holden1d"`` -- a Holden et al. style 1D temporal conv AE: features are channels, one conv of width 25
  (D -> 256) + ReLU + max-pool over time, nearest-neighbour un-pooling and a width-25 conv back to D.

Residual form (``cfg.model.residual``; not the paper): :func:`apply` takes the mask too, pre-fills the missing
entries by linear interpolation (:func:`~inbetween_jax.models.cae.masks.linear_prefill`; ``cfg.model.fill =
"hermite"``: the limited cubic Hermite fill :func:`inbetween_jax.baselines.hermite_fill`), feeds the network
the pre-filled image and the mask as two input channels (``holden1d``: 2D feature channels) and returns the
pre-filled image plus the network's output.  The last conv is zero-initialised, so an untrained model
returns the pre-fill.  ``cfg.model.paste_known`` then replaces the known entries by the input's.
``cfg.model.skips`` (CAE only; not the paper) adds U-Net skip connections: each decoder unit concatenates the
matching encoder unit's activation before its pool to its first conv's output, so frame-level detail need not
pass the 3 x 8 bottleneck.

Odd sizes (pad / crop).  Pooling is "ceil" pooling: before each 2x pooling an odd axis is padded by one
row / frame with ``-inf`` (so the pad never wins the max; TF's ``padding='SAME'``).  Each decoder unit
upsamples by 2 and crops the result to the size the matching encoder level had, so the output always has
the input's exact shape (e.g. 69 x 240 -> 35 x 120 -> 18 x 60 -> 9 x 30 -> 5 x 15 -> 3 x 8 and back).
The feature axis is only pooled while it is >= 3 rows high.

All convolutions are stride-1 "SAME" convs (:func:`conv_same`) with XLA's own gradients.  (An earlier custom VJP
built the weight gradient from kh*kw shifted-slice matmuls; with jax 0.10.2 XLA's own is 1.1-3.8x faster per
layer, docs/results/speed.md.)  A stride-2 transposed conv is the stride-1 conv over the
zero-dilated input (equivalent up to the kernel flip, which a learned kernel absorbs), computed without the zeros
by :func:`conv_upsampled`: one 2x2 (or 3x2) conv on the low-resolution input whose output channels hold the
even and odd output phases.  A stride-2 conv is a stride-1 conv sampled every second row / frame.
Weights use Xavier (Glorot) uniform initialisation, biases zero; :func:`init_params` draws them from one
key split over the parameter leaves in their flattening order (``dec`` before ``enc``, ``b`` before ``w``).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.baselines.hermite_fill import hermite_fill
from inbetween_jax.models.cae.masks import linear_prefill

__all__ = ["conv_same", "conv_upsampled", "max_pool_ceil", "upsample_zeros", "level_sizes", "VARIANTS", "FILLS",
           "param_shapes", "init_params", "prefill", "apply", "encode", "decode", "conv", "num_params"]

VARIANTS = ("cae", "vanilla", "holden1d")
FILLS = ("linear", "hermite")
_DN = ("NHWC", "HWIO", "NHWC")


def conv_same(x, w):
    """Stride-1 'SAME' 2D convolution.  x: (B, H, W, Cin); w: (kh, kw, Cin, Cout) with odd kh, kw.

    Returns (B, H, W, Cout).
    """
    return jax.lax.conv_general_dilated(x, w, (1, 1), "SAME", dimension_numbers=_DN)


# Along an upsampled axis, 3 kernel taps d (offsets d - 1 on the zero-dilated input) become 2 output phases e
# (even, odd) x 2 taps t on the low-resolution input (offsets 0, +1): even outputs see tap 1 at offset 0, odd
# outputs tap 0 at offset 0 and tap 2 at offset +1.  _PHASES[e, t, d].
_PHASES = np.zeros((2, 2, 3), np.float32)
_PHASES[0, 0, 1] = _PHASES[1, 0, 0] = _PHASES[1, 1, 2] = 1.0


def conv_upsampled(z, w, up_h: bool = True):
    """``conv_same(upsample_zeros(z, up_h), w)`` without multiplying the inserted zeros (a quarter of the
    multiply-adds when both axes are upsampled).

    z: (B, H, W, Cin); w: (3, 3, Cin, Cout).  Returns (B, 2H or H, 2W, Cout).
    """
    ay = _PHASES if up_h else np.eye(3, dtype=np.float32)[None]     # (phases, taps, 3)
    w2 = jnp.einsum("ets,fuv,svco->tucefo", ay, _PHASES, w)           # (taps_h, taps_w, Cin, Eh, Ew, Cout)
    kh, kw, cin, eh, ew, cout = w2.shape
    zp = jnp.pad(z, ((0, 0), (0, 1) if up_h else (1, 1), (0, 1), (0, 0)))
    out = jax.lax.conv_general_dilated(zp, w2.reshape(kh, kw, cin, eh * ew * cout), (1, 1), "VALID",
                                       dimension_numbers=_DN)
    b, h, wd, _ = out.shape
    return out.reshape(b, h, wd, eh, ew, cout).transpose(0, 1, 3, 2, 4, 5).reshape(b, h * eh, wd * ew, cout)


def max_pool_ceil(x, pool_h: bool = True):
    """2x max-pool over (H if ``pool_h``) and W, padding an odd axis with -inf first.

    x: (B, H, W, C) -> (B, ceil(H/2) or H, ceil(W/2), C).
    """
    b, h, w, c = x.shape
    fh = 2 if pool_h else 1
    ph, pw = (-h) % fh, (-w) % 2
    if ph or pw:
        x = jnp.pad(x, ((0, 0), (0, ph), (0, pw), (0, 0)), constant_values=-jnp.inf)
    h2, w2 = (h + ph) // fh, (w + pw) // 2
    return x.reshape(b, h2, fh, w2, 2, c).max(axis=(2, 4))


def upsample_zeros(x, up_h: bool = True):
    """Zero-insertion upsampling (the input of a stride-2 transposed conv; the reference for
    :func:`conv_upsampled`).

    x: (B, H, W, C) -> (B, 2H or H, 2W, C) with x at the even positions.
    """
    b, h, w, c = x.shape
    fh = 2 if up_h else 1
    out = jnp.zeros((b, h * fh, w * 2, c), x.dtype)
    return out.at[:, ::fh, ::2].set(x)


def level_sizes(height: int, length: int, levels: int = 5) -> list:
    """(H, W) at every encoder level, input first: ``level_sizes(69, 240)[-1] == (3, 8)``.

    Returns ``levels + 1`` pairs; W halves (ceil) each level, H only while it is >= 3.
    """
    sizes = [(int(height), int(length))]
    for _ in range(levels):
        h, w = sizes[-1]
        sizes.append(((h + 1) // 2 if h >= 3 else h, (w + 1) // 2))
    return sizes



# ----------------------------------------------------------------------------- parameters
def _layer(cin: int, cout: int, kernel=(3, 3)) -> dict:
    return {"b": jax.ShapeDtypeStruct((int(cout),), jnp.float32),
            "w": jax.ShapeDtypeStruct(tuple(kernel) + (int(cin), int(cout)), jnp.float32)}


def _check_variant(variant: str) -> None:
    if variant not in VARIANTS:
        raise ValueError(f"unknown CAE variant {variant!r}; choose one of {VARIANTS}")


def param_shapes(cfg, num_features: int) -> dict:
    """The parameter tree of ``cfg.model`` as ``jax.ShapeDtypeStruct`` leaves (see the module docstring).

    ``num_features`` (D) only matters for ``holden1d`` (its convs map D <-> hidden channels).
    """
    m = cfg.model
    _check_variant(m.variant)
    if m.fill not in FILLS:
        raise ValueError(f"unknown model.fill {m.fill!r}; choose one of {FILLS}")
    cin = 2 if m.residual else 1
    if m.variant == "holden1d":
        return {"dec": _layer(m.holden_hidden, num_features, (1, m.holden_width)),
                "enc": _layer(cin * num_features, m.holden_hidden, (1, m.holden_width))}
    channels = tuple(int(c) for c in m.channels)
    ins = (cin,) + channels[:-1]
    reps = 2 if m.variant == "cae" else 1
    enc = [[_layer(ci if r == 0 else co, co) for r in range(reps)] for ci, co in zip(ins, channels)]
    if m.skips and m.variant != "cae":
        raise ValueError(f"model.skips needs model.variant=cae, not {m.variant!r}")
    dec = []   # decoder unit u mirrors encoder unit L-1-u: c_in -> (c_in [+ skip] ->) target
    for ci, co in zip(reversed(channels), reversed(ins)):
        dec.append([_layer(ci, ci), _layer(ci * (2 if m.skips else 1), co)] if reps == 2 else [_layer(ci, co)])
    return {"dec": dec, "enc": enc}


def init_params(key, cfg, num_features: int) -> dict:
    """Xavier-uniform weights (biases zero) drawn from ``key``: one subkey per leaf, in flattening order.
    With ``cfg.model.residual`` the output conv's weights are zero too (the untrained model is the linear fill).

    key: a PRNG key; cfg: the model's Config; num_features: D.  Returns the nested dict of float32 arrays.
    """
    leaves, tree = jax.tree.flatten(param_shapes(cfg, num_features))
    keys = jax.random.split(key, len(leaves))
    init = jax.nn.initializers.xavier_uniform()
    params = jax.tree.unflatten(tree, [init(k, s.shape, s.dtype) if len(s.shape) >= 2
                                       else jnp.zeros(s.shape, s.dtype) for k, s in zip(keys, leaves)])
    if cfg.model.residual:
        last = params["dec"] if cfg.model.variant == "holden1d" else params["dec"][-1][-1]
        last["w"] = jnp.zeros_like(last["w"])
    return params


def num_params(params) -> int:
    return int(sum(x.size for x in jax.tree.leaves(params)))


# ----------------------------------------------------------------------------- apply
def conv(layer: dict, x):
    """'SAME' conv with bias: ``layer = {"b", "w": (kh, kw, Cin, Cout)}``; (B, H, W, Cin) -> (B, H, W, Cout)."""
    return conv_same(x, layer["w"]) + layer["b"]


def encode(params: dict, x, cfg, with_skips: bool = False):
    """CAE / Vanilla AE encoder: (B, D, T) or (B, D, T, C) -> (latent (B, h, w, C'), sizes [(H, W) per level,
    input first]) [, skips: each CAE unit's activation before its pool, (B, H_k, W_k, C_k), when ``with_skips``]."""
    m = cfg.model
    h = x[..., None] if x.ndim == 3 else x
    sizes, skips = [h.shape[1:3]], []
    for unit in params["enc"]:
        pool_h = h.shape[1] >= 3
        if m.variant == "cae":
            for layer in unit:
                h = jax.nn.leaky_relu(conv(layer, h), float(m.leak))
            skips.append(h)
            h = max_pool_ceil(h, pool_h)
        else:  # strided conv: stride-1 SAME conv sampled at even positions (ceil(n/2) outputs)
            h = jax.nn.leaky_relu(conv(unit[0], h), float(m.leak))
            h = h[:, ::2 if pool_h else 1, ::2]
        sizes.append(h.shape[1:3])
    return (h, sizes, skips) if with_skips else (h, sizes)


def decode(params: dict, z, sizes, cfg, skips=None):
    """CAE / Vanilla AE decoder: latent (B, h, w, C) + encoder sizes -> (B, D, T).  ``skips`` (U-Net,
    ``model.skips``): the encoder's pre-pool activations, concatenated to each unit's first conv output."""
    leak = float(cfg.model.leak)
    h = z
    n = len(params["dec"])
    for u, unit in enumerate(params["dec"]):
        th, tw = sizes[n - 1 - u]
        up_h = th > h.shape[1]
        for r, layer in enumerate(unit):
            h = conv_upsampled(h, layer["w"], up_h) + layer["b"] if r == 0 else conv(layer, h)
            if r == 0:
                h = h[:, :th, :tw]
                if skips is not None:
                    h = jnp.concatenate([jax.nn.leaky_relu(h, leak), skips[n - 1 - u]], axis=-1)
                    continue
            if not (u == n - 1 and r == len(unit) - 1):
                h = jax.nn.leaky_relu(h, leak)
    return h[..., 0]


def _holden(params: dict, x):
    """conv(width W, D -> hidden) + ReLU + max-pool(2, time, ceil) -> nearest un-pool -> conv(hidden -> D).

    x: (B, D_in, T) -> (B, D, T) (D_in = 2D in the residual form: features then mask rows)."""
    t = x.shape[-1]
    h = jnp.swapaxes(x, 1, 2)[:, None]                                  # (B, 1, T, D)
    h = max_pool_ceil(jax.nn.relu(conv(params["enc"], h)), pool_h=False)  # (B, 1, ceil(T/2), H)
    h = jnp.repeat(h, 2, axis=2)[:, :, :t]
    return jnp.swapaxes(conv(params["dec"], h)[:, 0], 1, 2)


def _network(params: dict, x, cfg):
    if cfg.model.variant == "holden1d":
        return _holden(params, x if x.ndim == 3 else jnp.concatenate([x[..., 0], x[..., 1]], axis=1))
    z, sizes, skips = encode(params, x, cfg, with_skips=True)
    return decode(params, z, sizes, cfg, skips if cfg.model.skips else None)


def prefill(x, mask, fill: str = "linear"):
    """The residual form's pre-filled image (``model.fill``): ``"linear"``
    (:func:`~inbetween_jax.models.cae.masks.linear_prefill`) or ``"hermite"`` (limited cubic Hermite,
    :func:`inbetween_jax.baselines.hermite_fill`).  x: (..., D, T); mask broadcastable, 1 = known."""
    if fill == "linear":
        return linear_prefill(x, mask)
    if fill == "hermite":
        return hermite_fill(jnp.asarray(x, jnp.float32), jnp.asarray(mask))
    raise ValueError(f"unknown model.fill {fill!r}; choose one of {FILLS}")


def apply(params: dict, x, cfg, mask=None):
    """The network of ``cfg.model.variant``: x (B, D, T) -> (B, D, T) for any T >= 1.

    x is the masked input ``x * mask``; ``mask`` (broadcastable to x, 1 = known; None: all known) is used
    only by the residual form / ``paste_known`` (the paper's model sees ``x * mask`` alone).
    """
    m = cfg.model
    _check_variant(m.variant)
    if mask is None and (m.residual or m.paste_known):
        mask = jnp.ones_like(x)
    if m.residual:
        mask = jnp.broadcast_to(mask, x.shape).astype(x.dtype)
        base = prefill(x, mask, m.fill)
        out = base + _network(params, jnp.stack([base, mask], axis=-1), cfg)
    else:
        out = _network(params, x, cfg)
    if m.paste_known:
        out = jnp.where(mask > 0.5, x, out)
    return out
