"""S-CVAE representation: frames <-> network inputs, feature statistics, training windows and phase labels.

A *frame* is a dict of arrays for a batch B on a skeleton of J joints::

    q (B, J, 4) local quaternions (w, x, y, z)    r (B, 3) global root position
    v (B, 3)   root velocity in the generator's own time direction (r_t - r_{t-1})
    c (B, 4)   foot contacts in [0, 1]             phase (B, 4) local-phase vector (2 feet x (sin, cos))

``stats`` (:func:`compute_stats`) holds the feature scales and the skeleton's bone offsets.

Phase labels (NumPy, data preparation; paper 3.3, "Phase Modulation").  The paper labels data with the
*local motion phases* of Starke et al. 2020 [36]: one phase per contact-bearing body part, derived from its
binary contact signal.  We use the two feet (contact = ankle OR toe).  Where [36] fits a sinusoid to the
contact signal in a sliding window, we use its closed form for a square wave: the phase advances by exactly
half a cycle between consecutive contact changes (touch-down at phase 0, lift-off at phase 0.5), linearly in
between and extrapolated at the window ends with the neighbouring segment's rate.  The amplitude is 2x the
local standard deviation of the contact signal over a +-``half_window``-frame window (1 for a regular gait,
0 for a foot that never changes state, where phase is meaningless).  The phase vector per foot is
``A * (sin 2 pi phi, cos 2 pi phi)``; 2 feet give the 4 inputs of the gating network (4-64-32-4).  The phase
*network* that predicts it lives in :mod:`inbetween_jax.models.scvae.model`.
"""
from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from inbetween_jax.data import l2p_stats
from inbetween_jax.data.features import offsets_to_target

PHASE_DIM = 4


def dims(num_joints: int) -> dict:
    """Feature sizes: state 4J+3+4 (95 on LaFAN1), offset 3+4J (91), target 4J (88), decoder output 4J+3+4."""
    return {"state": 4 * num_joints + 7, "offset": 4 * num_joints + 3, "target": 4 * num_joints,
            "out": 4 * num_joints + 7}


# ----------------------------------------------------------------------------- network inputs (JAX)
def state_features(f: dict, stats: dict):
    """(B, 4J+7): local quats, normalised root velocity, contacts."""
    b = f["q"].shape[0]
    return jnp.concatenate([f["q"].reshape(b, -1), f["v"] / stats["v_std"], f["c"]], axis=-1)


def offset_features(cur: dict, tgt_q, tgt_r, stats: dict):
    """(B, 3+4J): root-position offset (scaled) and element-wise local-quaternion offset to the target."""
    b = cur["q"].shape[0]
    off_r, off_q = offsets_to_target(cur["r"], cur["q"], tgt_r, tgt_q)
    return jnp.concatenate([off_r / stats["off_std"], off_q.reshape(b, -1)], axis=-1)


def reverse_time(f: dict) -> dict:
    """Frame(s) as seen by the generator running the other way in time (velocity negated)."""
    return dict(f, v=-f["v"])


# ----------------------------------------------------------------------------- statistics and training windows
def compute_stats(windows) -> dict:
    """Feature scales from training windows (MotionWindows): v_std (3,), off_std (3,), pos_unit (),
    offsets (J, 3)."""
    r = windows.root_pos.astype(np.float64)
    v = r[:, 1:] - r[:, :-1]
    off = r[:, None, :, :] - r[:, :, None, :]
    _, gp = windows.global_pose()
    _, x_std = l2p_stats(gp)
    return {"v_std": np.maximum(v.reshape(-1, 3).std(0), 1e-2).astype(np.float32),
            "off_std": np.maximum(np.sqrt((off ** 2).reshape(-1, 3).mean(0)), 1.0).astype(np.float32),
            "pos_unit": np.float32(x_std.mean()),
            "offsets": windows.offsets.astype(np.float32)}


def stats_like(num_joints: int) -> dict:
    """Zero statistics with the shapes and dtypes of :func:`compute_stats` (restore targets)."""
    return {"v_std": np.zeros(3, np.float32), "off_std": np.zeros(3, np.float32), "pos_unit": np.float32(0),
            "offsets": np.zeros((num_joints, 3), np.float32)}


@dataclasses.dataclass
class TrainData:
    """Training windows with their phase labels (NumPy), and what the run metadata records: ``skeleton``,
    ``fps``, ``stats`` (:func:`compute_stats`), ``provenance`` (files, counts, split) and ``extra``."""
    q: np.ndarray        # (N, T, J, 4)
    r: np.ndarray        # (N, T, 3)
    c: np.ndarray        # (N, T, 4)
    phase_f: np.ndarray  # (N, T, 4)
    phase_b: np.ndarray  # (N, T, 4)
    p: np.ndarray        # (N, T, J, 3) global joint positions
    parents: tuple
    skeleton: object = None
    fps: float | None = None
    stats: dict | None = None
    provenance: dict = dataclasses.field(default_factory=dict)
    extra: dict = dataclasses.field(default_factory=dict)
    names: tuple = ()    # (N,) window names "<file stem>@<first frame>"
    bank: object = None  # model.bank_base: the TransitionBank of the training files

    @classmethod
    def from_windows(cls, w, **meta) -> "TrainData":
        """From MotionWindows ``w``; ``meta``: stats / provenance / extra."""
        pf = phase_labels(w.contacts)
        pb = phase_labels(w.reversed().contacts)[:, ::-1].copy()   # labelled on the reversed motion
        return cls(w.local_quats.astype(np.float32), w.root_pos.astype(np.float32), w.contacts.astype(np.float32),
                   pf, pb, w.global_pose()[1], tuple(w.parents), w.skeleton, float(w.fps),
                   names=tuple(w.seq_names), **meta)

    def __len__(self):
        return self.q.shape[0]


# ----------------------------------------------------------------------------- phase labels (NumPy)
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


def keyframe_contacts(motion, frame: int, velfactor: float, side: str | None = None) -> np.ndarray:
    """(4,) foot contacts of one frame, from its displacement to the next frame (previous for the last).

    side: ``"start"`` / ``"end"`` for a keyframe that starts / ends a fill, whose frames are never read: a start
    keyframe's displacement is from the frame before it, an end keyframe's to the frame after it; with no such
    frame the feet count as still (every foot in contact)."""
    from inbetween_jax.data.features import foot_contacts
    from inbetween_jax.geometry import forward_kinematics
    n = motion.num_frames
    if side not in (None, "start", "end"):
        raise ValueError(f"side must be None, 'start' or 'end', not {side!r}")
    if side == "start":
        a, b = (frame - 1, frame) if frame >= 1 else (frame, frame)
    elif side == "end":
        a, b = (frame, frame + 1) if frame + 1 < n else (frame, frame)
    elif n < 2:
        return np.zeros(4, np.float32)
    else:
        a, b = (frame, frame + 1) if frame + 1 < n else (frame - 1, frame)
    _, gp = forward_kinematics(motion.local_quats[[a, b]], motion.local_pos[[a, b]], motion.skeleton.parents)
    return foot_contacts(gp[:, list(motion.skeleton.foot_joints())], velfactor)[0]


def past_frame_inputs(start: dict, yaw, q0) -> dict:
    """The start keyframe's ``v`` (1, 3) root displacement from the frame before and ``qp`` (1, J, 4) that
    frame's local quaternions, turned into the canonical space (``yaw``: canonical -> world root rotation) and
    sign-aligned to the canonical start keyframe ``q0`` (J, 4), as consecutive training frames are."""
    from inbetween_jax.data.user_input import check_unit_quats
    from inbetween_jax.geometry.quaternion import quat_align, quat_inv, quat_mul, quat_rotate
    qp = np.array(check_unit_quats(start["qp"], "start's previous frame q"), np.float64)
    inv = quat_inv(np.asarray(yaw, np.float64))
    qp[0] = quat_mul(inv, qp[0])
    qp = quat_align(qp, np.asarray(q0, np.float64))
    v = quat_rotate(inv, np.asarray(start["r"], np.float64) - np.asarray(start["rp"], np.float64))
    if not np.all(np.isfinite(v)):
        raise ValueError(f"start's previous frame r: expected 3 finite numbers, got {start['rp']!r}")
    return {"v": jnp.asarray(v[None], jnp.float32), "qp": jnp.asarray(qp[None], jnp.float32)}
