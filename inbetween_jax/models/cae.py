"""Convolutional inpainting autoencoder for motion infilling (Kaufmann et al., "Convolutional Autoencoders
for Human Motion Infilling", 3DV 2020) and its two network baselines.

A motion clip is an "image" ``x`` of shape ``(B, D, T)``: D feature rows (root-relative joint positions,
root velocities; see :mod:`inbetween_jax.models.cae_data`) by T frames.  Every model maps
``(B, D, T) -> (B, D, T)`` for any D >= 1 and T >= 1 (fully convolutional).

Variants (``make_model(variant=...)``):

* ``"cae"`` -- the paper's model (Fig. 4): 5 encoding units of two 3x3 convs + leaky ReLU followed by a
  2x2 max-pool; a mirrored, weight-decoupled decoder whose units are a stride-2 3x3 transposed conv then a
  3x3 conv (leaky ReLU after each, none on the very last output).  Channels (32, 64, 128, 256, 256) give a
  3 x 8 x 256 latent for a 69 x 240 input, as in the paper.
* ``"vanilla"`` -- the paper's "Vanilla AE": one strided 3x3 conv per encoding unit and one strided 3x3
  transposed conv per decoding unit (same channels).
* ``"holden1d"`` -- a Holden et al. style 1D temporal conv AE: features are channels, one conv of width 25
  (D -> 256) + ReLU + max-pool over time, nearest-neighbour un-pooling and a width-25 conv back to D.

Odd sizes (pad / crop).  Pooling is "ceil" pooling: before each 2x pooling an odd axis is padded by one
row / frame with ``-inf`` (so the pad never wins the max; TF's ``padding='SAME'``).  Each decoder unit
upsamples by 2 and crops the result to the size the matching encoder level had, so the output always has
the input's exact shape (e.g. 69 x 240 -> 35 x 120 -> 18 x 60 -> 9 x 30 -> 5 x 15 -> 3 x 8 and back).
The feature axis is only pooled while it is >= 3 rows high.

All convolutions are stride-1 "SAME" convs through :func:`conv_same`, whose custom VJP computes the weight
gradient as kh*kw shifted-slice matmuls (XLA:CPU's own conv weight gradient is slow).  A stride-2
transposed conv is a stride-1 conv over the zero-dilated input (equivalent up to the kernel flip, which a
learned kernel absorbs); a stride-2 conv is a stride-1 conv sampled every second row / frame.
Weights use Xavier (Glorot) uniform initialisation, biases zero.
"""
from __future__ import annotations

from typing import Sequence

import jax
import jax.numpy as jnp
from flax import nnx

__all__ = ["conv_same", "max_pool_ceil", "upsample_zeros", "InpaintingCAE", "Holden1DAE", "make_model",
           "level_sizes", "VARIANTS"]

VARIANTS = ("cae", "vanilla", "holden1d")
_DN = ("NHWC", "HWIO", "NHWC")


def _conv(x, w):
    return jax.lax.conv_general_dilated(x, w, (1, 1), "SAME", dimension_numbers=_DN)


@jax.custom_vjp
def conv_same(x, w):
    """Stride-1 'SAME' 2D convolution.  x: (B, H, W, Cin); w: (kh, kw, Cin, Cout) with odd kh, kw.

    Returns (B, H, W, Cout).  Same value as ``lax.conv_general_dilated``; only the backward pass differs.
    """
    return _conv(x, w)


def _conv_fwd(x, w):
    return _conv(x, w), (x, w)


def _conv_bwd(res, g):
    x, w = res
    kh, kw, cin, _ = w.shape
    (dx,) = jax.linear_transpose(lambda x_: _conv(x_, w), x)(g)   # no dead forward conv in the jaxpr
    h, wd = x.shape[1], x.shape[2]
    xp = jnp.pad(x, ((0, 0), (kh // 2, kh // 2), (kw // 2, kw // 2), (0, 0)))
    g2 = g.reshape(-1, g.shape[-1])
    dw = jnp.stack([jnp.stack([
        jnp.dot(xp[:, i:i + h, j:j + wd, :].reshape(-1, cin).T, g2, preferred_element_type=jnp.float32)
        for j in range(kw)]) for i in range(kh)])
    return dx, dw.astype(w.dtype)


conv_same.defvjp(_conv_fwd, _conv_bwd)


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
    """Zero-insertion upsampling (the input of a stride-2 transposed conv).

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


def _xavier():
    return nnx.initializers.xavier_uniform()


class Conv(nnx.Module):
    """'SAME' conv with bias.  (B, H, W, Cin) -> (B, H, W, Cout); kernel (kh, kw)."""

    def __init__(self, cin: int, cout: int, kernel: Sequence[int] = (3, 3), *, rngs: nnx.Rngs):
        self.w = nnx.Param(_xavier()(rngs.params(), tuple(kernel) + (cin, cout), jnp.float32))
        self.b = nnx.Param(jnp.zeros((cout,), jnp.float32))

    def __call__(self, x):
        return conv_same(x, self.w[...]) + self.b[...]


class InpaintingCAE(nnx.Module):
    """The paper's CAE (``variant="cae"``) or its Vanilla AE (``variant="vanilla"``).

    Args:
        channels: output channels of the encoding units (paper: (32, 64, 128, 256, 256)).
        variant: ``"cae"`` (two convs per unit, max-pool) or ``"vanilla"`` (one strided conv per unit).
        leak: negative slope of the leaky ReLU.
    Call: ``(B, D, T) -> (B, D, T)``.
    """

    def __init__(self, channels: Sequence[int] = (32, 64, 128, 256, 256), variant: str = "cae",
                 leak: float = 0.2, *, rngs: nnx.Rngs):
        if variant not in ("cae", "vanilla"):
            raise ValueError(f"InpaintingCAE variant must be 'cae' or 'vanilla', got {variant!r}")
        self.variant, self.leak, self.channels = variant, float(leak), tuple(int(c) for c in channels)
        ins = (1,) + self.channels[:-1]
        reps = 2 if variant == "cae" else 1
        self.enc = nnx.List([nnx.List([Conv(ci if r == 0 else co, co, rngs=rngs) for r in range(reps)])
                             for ci, co in zip(ins, self.channels)])
        # decoder unit u mirrors encoder unit L-1-u: c_in -> (c_in ->) target
        dec = []
        for ci, co in zip(reversed(self.channels), reversed(ins)):
            if reps == 2:
                dec.append(nnx.List([Conv(ci, ci, rngs=rngs), Conv(ci, co, rngs=rngs)]))
            else:
                dec.append(nnx.List([Conv(ci, co, rngs=rngs)]))
        self.dec = nnx.List(dec)

    def _act(self, x):
        return jax.nn.leaky_relu(x, self.leak)

    def encode(self, x):
        """(B, D, T) -> (latent (B, h, w, C), sizes [(H, W) per level, input first])."""
        h = x[..., None]
        sizes = [h.shape[1:3]]
        for unit in self.enc:
            pool_h = h.shape[1] >= 3
            if self.variant == "cae":
                for conv in unit:
                    h = self._act(conv(h))
                h = max_pool_ceil(h, pool_h)
            else:  # strided conv: stride-1 SAME conv sampled at even positions (ceil(n/2) outputs)
                h = self._act(unit[0](h))
                h = h[:, ::2 if pool_h else 1, ::2]
            sizes.append(h.shape[1:3])
        return h, sizes

    def decode(self, z, sizes):
        """latent (B, h, w, C) + encoder sizes -> (B, D, T)."""
        h = z
        n = len(self.dec)
        for u, unit in enumerate(self.dec):
            th, tw = sizes[n - 1 - u]
            up_h = th > h.shape[1]
            h = upsample_zeros(h, up_h)
            for r, conv in enumerate(unit):
                h = conv(h)
                if r == 0:
                    h = h[:, :th, :tw]
                if not (u == n - 1 and r == len(unit) - 1):
                    h = self._act(h)
        return h[..., 0]

    def __call__(self, x):
        z, sizes = self.encode(x)
        return self.decode(z, sizes)


class Holden1DAE(nnx.Module):
    """Holden et al. style 1D temporal conv AE: features are channels.

    ``(B, D, T) -> (B, D, T)``: conv(width 25, D -> hidden) + ReLU + max-pool(2, time, ceil)
    -> nearest un-pool (crop to T) -> conv(width 25, hidden -> D), no output activation.
    """

    def __init__(self, num_features: int, hidden: int = 256, width: int = 25, *, rngs: nnx.Rngs):
        self.enc = Conv(num_features, hidden, (1, width), rngs=rngs)
        self.dec = Conv(hidden, num_features, (1, width), rngs=rngs)

    def __call__(self, x):
        t = x.shape[-1]
        h = jnp.swapaxes(x, 1, 2)[:, None]                      # (B, 1, T, D)
        h = max_pool_ceil(jax.nn.relu(self.enc(h)), pool_h=False)  # (B, 1, ceil(T/2), H)
        h = jnp.repeat(h, 2, axis=2)[:, :, :t]
        return jnp.swapaxes(self.dec(h)[:, 0], 1, 2)


def make_model(variant: str, num_features: int, channels: Sequence[int] = (32, 64, 128, 256, 256),
               leak: float = 0.2, holden_hidden: int = 256, holden_width: int = 25, seed: int = 0,
               rngs: nnx.Rngs | None = None):
    """Build a model by name (one of :data:`VARIANTS`); ``num_features`` is D."""
    rngs = rngs if rngs is not None else nnx.Rngs(seed)
    if variant in ("cae", "vanilla"):
        return InpaintingCAE(channels, variant, leak, rngs=rngs)
    if variant == "holden1d":
        return Holden1DAE(num_features, holden_hidden, holden_width, rngs=rngs)
    raise ValueError(f"unknown CAE variant {variant!r}; choose one of {VARIANTS}")
