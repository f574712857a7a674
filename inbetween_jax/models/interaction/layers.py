"""Network blocks of the interaction in-betweening model (flax NNX, used through
:mod:`inbetween_jax.models.interaction.model`, whose parameters are plain nested dicts).

* :class:`GraphConv` -- ``A x W`` over joints with a learnable adjacency ``A`` (J, J), as in DCT-GCN motion
  prediction (Mao et al. 2019).
* :class:`ConvGCN` -- 1D convolutions over the DCT-coefficient axis of each joint, then residual GCN layers:
  the encoder / decoder architecture of the cross-space in-betweening network.
* :class:`FiLM` -- latent z (..., Z) -> scale / shift (..., H);  ``h * (1 + gamma) + beta``.
* :class:`Refiner` -- autoencoder + GCN over 10-frame segments (DCT in, residual DCT out).
* :class:`PeriodicAE` -- DeepPhase periodic autoencoder with FFT-parameterised phase channels.
* :class:`Discriminator` -- MLP on the periodic latent (interaction GAN / evaluation classifier).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from inbetween_jax.geometry import dct, idct


class GraphConv(nnx.Module):
    """x (B, J, F) -> (B, J, O): ``A @ x @ W + b`` with learnable A (init: identity + small noise)."""

    def __init__(self, num_joints: int, features: int, out: int, *, rngs: nnx.Rngs):
        noise = 0.01 * jax.random.normal(rngs.params(), (num_joints, num_joints))
        self.adj = nnx.Param(jnp.eye(num_joints) + noise)
        self.lin = nnx.Linear(features, out, rngs=rngs)

    def __call__(self, x):
        return jnp.einsum("ij,bjf->bif", self.adj[...], self.lin(x))


def conv_same(conv: nnx.Conv, x):
    """``conv(x)`` of a 1D :class:`nnx.Conv` (odd kernel, stride 1, ``'SAME'`` padding) on x (B, N, C) -> (B, N,
    O), computed as one matmul with the banded (Toeplitz) matrix of its kernel.  At these few channels and
    positions XLA:CPU's convolutions (and their gradients) cost far more than the multiply-adds; with the
    ensemble's members side by side (or vmapped) the matmul made the training step 1.3-1.5x faster, while one
    member alone runs equally fast either way (docs/results/speed.md).  The same function and parameters; the
    sums run in another order."""
    w = conv.kernel[...]                                            # (k, C, O)
    k, C, O = w.shape
    N = x.shape[1]
    t, i, o = np.meshgrid(np.arange(k), np.arange(N), np.arange(N), indexing="ij")
    taps = (i == o + t - (k - 1) // 2).astype(np.float32)           # (k, N_in, N_out): tap t links i to o
    band = jnp.einsum("tio,tcd->icod", taps, w).reshape(N * C, N * O)
    y = (x.reshape(x.shape[0], N * C) @ band).reshape(x.shape[0], N, O)
    return y if conv.bias is None else y + conv.bias[...]


class ConvGCN(nnx.Module):
    """Conv1d over coefficients + GCN over joints.

    x (B, J, K, C) (or (B, J, C) with ``conv=False``), extra (B, J, E) or None ->
    (features (B, J, H), out (B, J, O)).  ``out_init``: the output layer's kernel initialiser (default
    normal(1e-3); zeros for a residual head that starts at exactly zero).
    """

    def __init__(self, num_joints: int, K: int, C: int, E: int, H: int, O: int, conv_ch: int, n_gcn: int,
                 *, conv: bool = True, out_init=None, rngs: nnx.Rngs):
        self.conv = conv
        if conv:
            self.c1 = nnx.Conv(C, conv_ch, 3, rngs=rngs)
            self.c2 = nnx.Conv(conv_ch, conv_ch, 3, rngs=rngs)
            din = K * conv_ch + E
        else:
            din = C + E
        self.proj = nnx.Linear(din, H, rngs=rngs)
        self.gcn = nnx.List([GraphConv(num_joints, H, H, rngs=rngs) for _ in range(n_gcn)])
        self.norms = nnx.List([nnx.LayerNorm(H, rngs=rngs) for _ in range(n_gcn)])
        self.out = nnx.Linear(H, O, kernel_init=out_init or nnx.initializers.normal(1e-3), rngs=rngs)

    def __call__(self, x, extra=None):
        B, J = x.shape[:2]
        if self.conv:
            K, C = x.shape[2:]
            h = x.reshape(B * J, K, C)
            h = jnp.tanh(conv_same(self.c1, h))
            h = jnp.tanh(conv_same(self.c2, h))
            h = h.reshape(B, J, -1)
        else:
            h = x
        if extra is not None:
            h = jnp.concatenate([h, extra], -1)
        h = jnp.tanh(self.proj(h))
        for g, n in zip(self.gcn, self.norms):
            h = h + jnp.tanh(n(g(h)))
        return h, self.out(h)


class FiLM(nnx.Module):
    """z (..., Z) -> (gamma, beta) each (..., H); apply with :func:`film`."""

    def __init__(self, Z: int, H: int, *, rngs: nnx.Rngs):
        self.lin = nnx.Linear(Z, 2 * H, kernel_init=nnx.initializers.normal(1e-2), rngs=rngs)

    def __call__(self, z):
        g, b = jnp.split(self.lin(z), 2, axis=-1)
        return g, b


def film(h, gamma, beta):
    """Feature-wise linear modulation ``h * (1 + gamma) + beta`` (identity at gamma = beta = 0)."""
    return h * (1.0 + gamma) + beta


def reparameterize(mu, logvar, key, scale=1.0):
    """z = mu + scale * eps * exp(logvar / 2), eps ~ N(0, I): shapes (..., Z) (scale 0: the mean)."""
    return mu + scale * jax.random.normal(key, mu.shape, mu.dtype) * jnp.exp(0.5 * logvar)


class Refiner(nnx.Module):
    """Motion refiner on segments x (B, L, J, 9) -> refined (B, L, J, 9) (DCT autoencoder + GCN).

    ``identity_init``: the decoder's output layer starts at zero, so the untrained refiner returns its input."""

    def __init__(self, num_joints: int, L: int, H: int, Z: int, conv_ch: int, n_gcn: int, *, rngs: nnx.Rngs,
                 identity_init: bool = False):
        self.L = L
        zero = dict(out_init=nnx.initializers.zeros) if identity_init else {}
        self.enc = ConvGCN(num_joints, L, 9, 0, H, Z, conv_ch, n_gcn, rngs=rngs)
        self.dec = ConvGCN(num_joints, L, Z, 0, H, L * 9, conv_ch, n_gcn, conv=False, rngs=rngs, **zero)

    def __call__(self, x):
        B, L, J, C = x.shape
        c = jnp.moveaxis(dct(x, axis=1), 1, 2)                 # (B, J, L, 9)
        _, z = self.enc(c)
        _, r = self.dec(jnp.tanh(z))
        c = c + r.reshape(B, J, L, C)
        return idct(jnp.moveaxis(c, 2, 1), n=L, axis=1)


class PeriodicAE(nnx.Module):
    """DeepPhase periodic autoencoder: x (B, N, C_in) -> (recon (B, N, C_in), h (B, N, Cp), params).

    Latent curves (B, N, Cp) from 1D convolutions; per channel, the FFT gives frequency f (power-weighted
    mean, cycles per frame), amplitude a and offset b; a per-channel FC gives the phase phi; the periodic
    latent is ``h = a sin(2 pi (f t + phi)) + b`` (Eq. 10).  params: dict of (B, Cp) arrays f, a, b, phi.
    """

    def __init__(self, C_in: int, N: int, Cp: int, hidden: int, *, rngs: nnx.Rngs):
        self.N = N
        self.e1 = nnx.Conv(C_in, hidden, 5, rngs=rngs)
        self.e2 = nnx.Conv(hidden, Cp, 5, rngs=rngs)
        self.phase_w = nnx.Param(jax.random.normal(rngs.params(), (Cp, N, 2)) / np.sqrt(N))
        self.phase_b = nnx.Param(jnp.zeros((Cp, 2)))
        self.d1 = nnx.Conv(Cp, hidden, 5, rngs=rngs)
        self.d2 = nnx.Conv(hidden, C_in, 5, rngs=rngs)

    def encode(self, x):
        N = x.shape[1]
        lat = self.e2(jax.nn.elu(self.e1(x)))                      # (B, N, Cp)
        spec = jnp.fft.rfft(lat, axis=1)                           # (B, N//2+1, Cp)
        power = jnp.abs(spec[:, 1:]) ** 2
        freqs = jnp.arange(1, spec.shape[1], dtype=x.dtype)[None, :, None] / N
        psum = jnp.sum(power, axis=1) + 1e-8
        f = jnp.sum(power * freqs, axis=1) / psum
        a = 2.0 * jnp.sqrt(psum) / N
        b = jnp.real(spec[:, 0]) / N
        v = jnp.einsum("bnc,cnk->bck", lat, self.phase_w[...]) + self.phase_b[...]
        phi = jnp.arctan2(v[..., 1], v[..., 0]) / (2 * jnp.pi)
        t = (jnp.arange(N, dtype=x.dtype) - (N - 1) / 2.0)[None, :, None]
        h = a[:, None] * jnp.sin(2 * jnp.pi * (f[:, None] * t + phi[:, None])) + b[:, None]
        return h, dict(f=f, a=a, b=b, phi=phi)

    def __call__(self, x):
        h, params = self.encode(x)
        return self.d2(jax.nn.elu(self.d1(h))), h, params


class Discriminator(nnx.Module):
    """Periodic latent h (B, N, Cp) + params -> (logit (B,), features (B, H))."""

    def __init__(self, N: int, Cp: int, H: int, extra: int = 0, *, rngs: nnx.Rngs):
        self.l1 = nnx.Linear(N * Cp + 3 * Cp + extra, H, rngs=rngs)
        self.l2 = nnx.Linear(H, H, rngs=rngs)
        self.l3 = nnx.Linear(H, 1, rngs=rngs)

    def __call__(self, h, params, extra=None):
        parts = [h.reshape(h.shape[0], -1), params["f"], params["a"], params["b"]]
        if extra is not None:
            parts.append(extra)
        x = jax.nn.leaky_relu(self.l1(jnp.concatenate(parts, -1)), 0.2)
        feat = jax.nn.leaky_relu(self.l2(x), 0.2)
        return self.l3(feat)[:, 0], feat


def pjd_dynamics(pos_a, pos_b, joints=None, scale: float = 1.0):
    """Pairwise-joint-distance dynamics (Eq. 8-9): per-frame change of squared distances between every joint
    of character a and every joint of b.

    pos_a, pos_b: (B, N + 1, J, 3) positions in one common space -> (B, N, J'*J') with J' = len(joints).
    """
    if joints is not None and len(joints):
        idx = jnp.asarray(joints)
        pos_a, pos_b = pos_a[:, :, idx], pos_b[:, :, idx]
    d2 = jnp.sum((pos_a[:, :, :, None] - pos_b[:, :, None, :]) ** 2, -1)   # (B, N+1, J, J)
    d = (d2[:, 1:] - d2[:, :-1]) * scale
    return d.reshape(d.shape[0], d.shape[1], -1)
