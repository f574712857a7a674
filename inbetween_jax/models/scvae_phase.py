"""Phase for the S-CVAE decoder's phase modulation (paper 3.3, "Phase Modulation").

Labelling (NumPy, data preparation).  The paper labels data with the *local motion phases* of
Starke et al. 2020 [36]: one phase per contact-bearing body part, derived from its binary contact signal.
We use the two feet (contact = ankle OR toe).  Where [36] fits a sinusoid to the contact signal in a
sliding window, we use its closed form for a square wave: the phase advances by exactly half a cycle
between consecutive contact changes (touch-down at phase 0, lift-off at phase 0.5), linearly in between
and extrapolated at the window ends with the neighbouring segment's rate.  The amplitude is 2x the local
standard deviation of the contact signal over a +-``half_window``-frame window (1 for a regular gait,
0 for a foot that never changes state, where phase is meaningless).  The phase vector per foot is
``A * (sin 2 pi phi, cos 2 pi phi)``; 2 feet give the 4 inputs of the gating network (4-64-32-4).

Prediction (JAX).  A phase network (MLP) maps (local quaternions, normalised root velocity, contacts,
current phase vector) to a phase *update*; phase_{t+1} = phase_t + update, autoregressively as in [36].
The keyframe's phase is predicted from the keyframe with a zero phase input.  The network is trained by
its own L1 regression loss on the labels (teacher forcing) and receives no gradient from the generator
losses, which matches the paper's pre-trained phase network while training in the same step.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from inbetween_jax.models import scvae_nn as nn


def foot_phase(contact: np.ndarray, half_window: int = 15, default_rate: float = 1.0 / 30.0):
    """Local phase of one foot.  contact: (T,) in {0, 1} -> (phi (T,) unbounded cycles, amplitude (T,))."""
    c = (np.asarray(contact) > 0.5).astype(np.float64)
    t_len = c.shape[0]
    ev = np.nonzero(c[1:] != c[:-1])[0] + 1          # first frame of each new state
    tt = np.arange(t_len, dtype=np.float64)
    if len(ev) == 0:
        phi = np.zeros(t_len)
    else:
        val = np.empty(len(ev))
        val[0] = 0.0 if c[ev[0]] == 1 else 0.5
        val[1:] = val[0] + 0.5 * np.arange(1, len(ev))
        if len(ev) == 1:
            rate_a = rate_b = default_rate
        else:
            rate_a = 0.5 / max(ev[1] - ev[0], 1)
            rate_b = 0.5 / max(ev[-1] - ev[-2], 1)
        phi = np.interp(tt, ev.astype(np.float64), val)
        phi = np.where(tt < ev[0], val[0] - (ev[0] - tt) * rate_a, phi)
        phi = np.where(tt > ev[-1], val[-1] + (tt - ev[-1]) * rate_b, phi)
    amp = np.empty(t_len)
    for t in range(t_len):
        lo, hi = max(0, t - half_window), min(t_len, t + half_window + 1)
        amp[t] = min(1.0, 2.0 * c[lo:hi].std())
    return phi, amp


def phase_labels(contacts: np.ndarray, half_window: int = 15) -> np.ndarray:
    """Phase vectors from LaFAN1-order contacts (l_ankle, l_toe, r_ankle, r_toe).

    contacts: (N, T, 4) -> (N, T, 4) float32 = [A_l sin, A_l cos, A_r sin, A_r cos].
    """
    contacts = np.asarray(contacts)
    out = np.zeros(contacts.shape[:2] + (4,), np.float32)
    for i in range(contacts.shape[0]):
        for f, (a, b) in enumerate(((0, 1), (2, 3))):
            foot = np.maximum(contacts[i, :, a], contacts[i, :, b])
            phi, amp = foot_phase(foot, half_window)
            out[i, :, 2 * f] = amp * np.sin(2 * np.pi * phi)
            out[i, :, 2 * f + 1] = amp * np.cos(2 * np.pi * phi)
    return out


def init_phase_net(f, d_in: int, hidden: int) -> list:
    """MLP (state features + 4 phase) -> hidden -> hidden -> 4 phase update."""
    return nn.init_mlp(f, (d_in, hidden, hidden, 4))


def phase_step(params: list, frame: dict, stats: dict, state_features) -> jnp.ndarray:
    """phase_{t+1} = phase_t + net([state_t, phase_t]).  frame needs q, v, c, phase; returns (B, 4)."""
    x = jnp.concatenate([state_features(frame, stats), frame["phase"]], -1)
    return frame["phase"] + nn.mlp(params, x)
