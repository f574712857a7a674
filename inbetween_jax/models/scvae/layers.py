"""Pure-function building blocks of the S-CVAE: dense / MLP / LSTM / mixture-of-experts on plain param pytrees,
and the time-to-arrival embedding.

Parameters are nested dicts of float32 arrays, declared by ``init_*`` on a :class:`ParamFactory` and
drawn from one explicit PRNG key by ``ParamFactory.materialize``.  The apply functions are pure (nothing
here holds state), so every model function can be ``jit``-ed, ``vmap``-ed and differentiated directly.
The optional ``tap`` arguments defer weight gradients (training speed only, see
:mod:`inbetween_jax.models.scvae.deferred_grads`).
"""
from __future__ import annotations

from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.models.scvae.deferred_grads import tapped_matmul


class _Slot:
    """Placeholder leaf for a parameter drawn later by :meth:`ParamFactory.materialize`."""
    __slots__ = ("index",)

    def __init__(self, index: int):
        self.index = index


class ParamFactory:
    """Collects parameter shapes, then draws *all* of them with one ``jax.random.uniform`` call.

    One draw keeps the jitted / ``eval_shape``-d initialiser tiny (a per-layer draw compiles one
    threefry kernel per layer).  ``uniform(shape, lim)`` returns a placeholder; ``materialize(tree, key)``
    replaces the placeholders by U(-lim, lim) arrays (float32).
    """

    def __init__(self):
        self.specs = []

    def uniform(self, shape, lim: float) -> _Slot:
        self.specs.append((tuple(int(d) for d in shape), float(lim)))
        return _Slot(len(self.specs) - 1)

    def materialize(self, tree, key):
        sizes = [int(np.prod(s)) for s, _ in self.specs]
        flat = jax.random.uniform(key, (sum(sizes),), jnp.float32, -1.0, 1.0)
        offs = np.concatenate([[0], np.cumsum(sizes)])
        arrays = [flat[o:o + n].reshape(s) * lim for o, n, (s, lim) in zip(offs[:-1], sizes, self.specs)]
        return jax.tree.map(lambda x: arrays[x.index] if isinstance(x, _Slot) else x, tree)


def init_dense(f: ParamFactory, d_in: int, d_out: int) -> dict:
    """PyTorch-style uniform init: W (d_in, d_out), b (d_out,) ~ U(-1/sqrt(d_in), 1/sqrt(d_in))."""
    lim = 1.0 / np.sqrt(d_in)
    return {"w": f.uniform((d_in, d_out), lim), "b": f.uniform((d_out,), lim)}


def init_mlp(f: ParamFactory, sizes: Sequence[int]) -> list:
    """Fully-connected layers ``sizes[0] -> sizes[1] -> ... -> sizes[-1]``."""
    return [init_dense(f, a, b) for a, b in zip(sizes[:-1], sizes[1:])]


def mlp(params: list, x, final_act: bool = False):
    """x (..., sizes[0]) -> (..., sizes[-1]); ELU between layers (and after the last if ``final_act``)."""
    for i, layer in enumerate(params):
        x = x @ layer["w"] + layer["b"]
        if i < len(params) - 1 or final_act:
            x = jax.nn.elu(x)
    return x


def init_lstm(f: ParamFactory, d_in: int, d_hidden: int) -> dict:
    """One LSTM cell: gates (i, f, g, o) from ``x @ wx + h @ wh + b``; forget bias initialised to 1."""
    lim = 1.0 / np.sqrt(d_hidden)
    b = np.zeros((4 * d_hidden,), np.float32)
    b[d_hidden:2 * d_hidden] = 1.0
    return {"wx": f.uniform((d_in, 4 * d_hidden), lim), "wh": f.uniform((d_hidden, 4 * d_hidden), lim),
            "b": jnp.asarray(b)}


def lstm_zero_carry(batch_shape, d_hidden: int):
    """(h, c), each (*batch_shape, d_hidden) zeros."""
    z = jnp.zeros(tuple(batch_shape) + (d_hidden,), jnp.float32)
    return (z, z)


def lstm_cell(gates, c):
    """LSTM update from pre-activation gates (..., 4H) in (i, f, g, o) order and cell c (..., H) -> (h, c)."""
    i, f, g, o = jnp.split(gates, 4, axis=-1)
    c = jax.nn.sigmoid(f) * c + jax.nn.sigmoid(i) * jnp.tanh(g)
    return jax.nn.sigmoid(o) * jnp.tanh(c), c


def lstm(params: dict, carry, x):
    """One step. carry (h, c) each (B, H); x (B, D). Returns (new_carry, h_new (B, H))."""
    h, c = carry
    h, c = lstm_cell(x @ params["wx"] + h @ params["wh"] + params["b"], c)
    return (h, c), h


def lstm_shared_carry(params: dict, carry, x1, x2, taps=None):
    """Two LSTM steps from the *same* carry on two inputs, as one matmul over 2B rows.

    ``h @ wh`` is computed once.  carry (h, c) each (B, H); x1, x2 (B, D).
    Returns (carry after x1, h1 (B, H), h2 (B, H)) -- equal to two :func:`lstm` calls.  ``taps``
    (optional ``{"enc_wh": (B, 4H), "enc_wx": (2B, 4H)}``) defer the weight gradients (:func:`tapped_matmul`).
    """
    h, c = carry
    b = h.shape[0]
    taps = taps or {}
    gh = tapped_matmul(h, params["wh"], taps.get("enc_wh")) + params["b"]
    gates = tapped_matmul(jnp.concatenate([x1, x2], axis=0), params["wx"], taps.get("enc_wx")) + \
        jnp.concatenate([gh, gh], axis=0)
    h2, c2 = lstm_cell(gates, jnp.concatenate([c, c], axis=0))
    return (h2[:b], c2[:b]), h2[:b], h2[b:]


def pack_lstm(params: dict) -> dict:
    """{"wx", "wh", "b"} -> {"w": [wx; wh] (D + H, 4H), "b"} for :func:`lstm_packed` (do it outside a scan)."""
    return {"w": jnp.concatenate([params["wx"], params["wh"]], axis=0), "b": params["b"]}


def lstm_packed(params: dict, carry, x, tap=None):
    """:func:`lstm` with packed weights: one ``[x, h] @ [wx; wh]`` matmul.  Same shapes and values.
    ``tap`` (B, 4H) defers the weight gradient (:func:`tapped_matmul`)."""
    h, c = carry
    h, c = lstm_cell(tapped_matmul(jnp.concatenate([x, h], axis=-1), params["w"], tap) + params["b"], c)
    return (h, c), h


def init_moe(f: ParamFactory, sizes: Sequence[int], num_experts: int, zero_last: bool = False) -> list:
    """Experts as stacked layers: W (E, d_in, d_out), b (E, d_out).  ``zero_last``: the output layer starts
    at zero (a residual head whose untrained output is exactly 0)."""
    n = len(sizes) - 1
    lim = [0.0 if zero_last and i == n - 1 else 1.0 / np.sqrt(a) for i, a in enumerate(sizes[:-1])]
    return [{"w": f.uniform((num_experts, a, b), lm), "b": f.uniform((num_experts, b), lm)}
            for a, b, lm in zip(sizes[:-1], sizes[1:], lim)]


def moe(params: list, x, alpha, tap=None):
    """Mixture of experts with blended *weights* (MANN-style): every layer uses ``sum_e alpha_e W_e``.

    Blending the weights of a linear layer equals blending its per-expert outputs before the
    activation, which is what is computed (no per-sample weight matrices are materialised).  Layers may
    be packed by :func:`pack_moe` (one (d_in, E * d_out) matmul per layer instead of E).
    x (B, d_in), alpha (B, E) (rows sum to 1) -> (B, d_out).  ``tap`` (B, E * d_out of the first layer)
    defers the first packed layer's weight gradient (:func:`tapped_matmul`).
    """
    for i, layer in enumerate(params):
        if "w_packed" in layer:
            e, o = layer["b"].shape
            y = tapped_matmul(x, layer["w_packed"], tap if i == 0 else None)
            y = y.reshape(x.shape[0], e, o) + layer["b"][None]
        else:
            y = jnp.einsum("bi,eio->beo", x, layer["w"]) + layer["b"][None]
        x = jnp.einsum("be,beo->bo", alpha, y)
        if i < len(params) - 1:
            x = jax.nn.elu(x)
    return x


def pack_moe(params: list) -> list:
    """Expert layers W (E, d_in, d_out) -> ``w_packed`` (d_in, E * d_out) (do it outside a scan)."""
    out = []
    for layer in params:
        e, i, o = layer["w"].shape
        out.append({"w_packed": jnp.transpose(layer["w"], (1, 0, 2)).reshape(i, e * o), "b": layer["b"]})
    return out


def tta_embedding(tta, dim: int, basis: float = 10000.0):
    """Time-to-arrival embedding (Eq. 11-12): z_{2i} = sin(tta / basis^(2i/d)), z_{2i+1} = cos(...).

    tta: (...) float -> (..., dim).
    """
    i = jnp.arange(dim // 2, dtype=jnp.float32)
    freq = basis ** (2.0 * i / dim)
    ang = jnp.asarray(tta, jnp.float32)[..., None] / freq
    return jnp.stack([jnp.sin(ang), jnp.cos(ang)], axis=-1).reshape(ang.shape[:-1] + (dim,))
