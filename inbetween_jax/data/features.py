"""Per-frame features derived from motion: unit scale, foot contacts, root velocity, normalisation statistics."""
from __future__ import annotations

import dataclasses

import numpy as np

from inbetween_jax.geometry.quaternion import _xp


# Unit detection: the root-to-ankle chain (hip offset + thigh + shin) of adult actors measures about 96.5 cm:
# 96.6 in LaFAN1, 94.9 in the CMU Daz/Poser conversion, 96-101 cm (17-18 units of 2.54 / 0.45 cm) in the five
# subjects of the CMU ASF-unit conversion. A skeleton whose leg is L file units is taken as 96.5 / L cm per unit.
REFERENCE_LEG_CM = 96.5
# Estimates within 5 % of a common unit are snapped to it (cm, mm, m, inch, CMU ASF unit = 1/0.45 inch).
KNOWN_UNITS_CM = (1.0, 0.1, 100.0, 2.54, 2.54 / 0.45)
_SNAP_RTOL = 0.05


def leg_length(skeleton) -> float:
    """Mean length (file units) of the bone chains from the root to the two ankle joints, from the offsets."""
    off = np.asarray(skeleton.offsets, np.float64)
    lengths = []
    for ankle in skeleton.foot_joints()[0::2]:
        total, j = 0.0, ankle
        while j > 0:
            total += float(np.linalg.norm(off[j]))
            j = skeleton.parents[j]
        lengths.append(total)
    return float(np.mean(lengths))


def detect_unit_scale(skeleton) -> float:
    """Centimetres per file unit of ``skeleton``'s offsets, estimated from its leg length (see
    :data:`REFERENCE_LEG_CM`): 1.0 for LaFAN1 and the embedded CMU data, 2.54 / 0.45 for CMU ASF-unit files,
    about 128 for the 1/128-scaled CMU salsa files.

    Estimates within 5 % of a unit in :data:`KNOWN_UNITS_CM` return that unit exactly, others are rounded to
    3 significant digits.  A skeleton without recognisable feet (or with zero-length legs) gives 1.0.  The
    estimate assumes an adult: pass an explicit scale for children, animals or unusual rigs.
    """
    try:
        leg = leg_length(skeleton)
    except KeyError:
        return 1.0
    if not np.isfinite(leg) or leg <= 0:
        return 1.0
    raw = REFERENCE_LEG_CM / leg
    for unit in KNOWN_UNITS_CM:
        if abs(raw / unit - 1.0) <= _SNAP_RTOL:
            return float(unit)
    return float(f"{raw:.3g}")


def unit_factor(skel, ref) -> float:
    """Reference units per file unit: the ratio of detected unit scales, or the exact leg-length ratio when
    it agrees with that ratio within 5 % (the same generic body at another scale)."""
    factor = detect_unit_scale(skel) / detect_unit_scale(ref)
    exact = leg_length(ref) / leg_length(skel)
    return exact if abs(exact / factor - 1.0) <= 0.05 else factor


def foot_contacts(foot_pos: np.ndarray, velfactor: float = 0.02, unit_scale: float = 1.0) -> np.ndarray:
    """LaFAN1 contact labels: a foot joint is in contact when its squared displacement to the next
    frame is below ``velfactor`` (cm^2 per frame^2); the last frame repeats the previous label.

    foot_pos: (T, F, 3) global positions of the F foot joints in file units, ``unit_scale`` cm per unit
    (:func:`detect_unit_scale`). Returns (T, F) float32 in {0, 1}.
    """
    if foot_pos.shape[0] < 2:
        return np.zeros(foot_pos.shape[:2], np.float32)
    sq = np.sum((foot_pos[1:] - foot_pos[:-1]) ** 2, axis=-1) * float(unit_scale) ** 2
    c = (sq < velfactor).astype(np.float32)
    return np.concatenate([c, c[-1:]], axis=0)


def root_velocity(root_pos):
    """Per-frame root displacement ``r_t - r_{t-1}`` (first frame zero): (..., T, 3) -> (..., T, 3).

    Computes in NumPy for NumPy input and in ``jax.numpy`` otherwise.
    """
    xp = _xp(root_pos)
    vel = root_pos[..., 1:, :] - root_pos[..., :-1, :]
    return xp.concatenate([xp.zeros_like(root_pos[..., :1, :]), vel], axis=-2)


def offsets_to_target(root_pos, local_quats, target_root, target_quats):
    """S-CVAE / RMIB offset features: element-wise differences ``target - current``.

    root_pos (..., 3) and local_quats (..., J, 4) of the current frame(s); the target's root (..., 3) and
    quaternions (..., J, 4) broadcast against them (add a time axis to the target for (..., T, ...) inputs).
    Returns (root offset (..., 3), quaternion offsets (..., J, 4)).
    """
    return target_root - root_pos, target_quats - local_quats


@dataclasses.dataclass
class Normalizer:
    """Feature-wise z-normalisation ``(x - mean) / std`` with std floored at ``eps``.

    mean, std: (D,) float32.
    """

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, x: np.ndarray, eps: float = 1e-4) -> "Normalizer":
        """Statistics over every axis but the last: x (..., D)."""
        flat = np.asarray(x, np.float64).reshape(-1, x.shape[-1])
        return cls(flat.mean(0).astype(np.float32), np.maximum(flat.std(0), eps).astype(np.float32))

    def __call__(self, x):
        return (x - self.mean) / self.std

    def inverse(self, x):
        return x * self.std + self.mean

    def to_dict(self) -> dict:
        return {"mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "Normalizer":
        return cls(np.asarray(d["mean"], np.float32), np.asarray(d["std"], np.float32))


def l2p_stats(global_pos: np.ndarray):
    """Official LaFAN1 L2P statistics from training windows' global positions.

    global_pos: (N, T, J, 3). Returns ``x_mean, x_std`` of shape (1, J*3, 1), as ``benchmarks.py``
    (mean / std over windows and frames of each flattened coordinate).
    """
    n, t = global_pos.shape[:2]
    x = np.asarray(global_pos, np.float64).reshape(n, t, -1).transpose(0, 2, 1)
    return x.mean(axis=(0, 2), keepdims=True), x.std(axis=(0, 2), keepdims=True)
