"""Knowing when a model does not know: an out-of-distribution score per window and a gate toward the base.

A learned in-between is only as good as the training motion near it.  Every model describes the context it is
given (its keyframes, or the known frames around a gap) as a fixed-length vector, and a :class:`ContextBank`
holds the same description of the training windows, projected on their principal components.  The score of a
context is the mean distance to its ``k`` nearest training contexts divided by the training contexts' own
median leave-one-out k-NN distance: about 1 inside the training motion, larger the farther a context lies from
it.  A :class:`Gate` turns the score into the weight of the learned fill,

    fill = base + w(score) (learned - base),   w = clip((hi - score) / (hi - lo), 0, 1),

so a context as familiar as the training motion (score <= lo) keeps the learned fill and one far from it
(score >= hi) falls back to the model's non-learned base (Slerp / lerp for the S-CVAE, the Hermite fill for the
CAE).  ``lo`` / ``hi`` are chosen on the validation subjects by :func:`calibrate_gate` from each window's error
at a few blend weights; nothing here looks at test windows.

NumPy only (host side); shapes: B contexts of D numbers.
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from inbetween_jax.errors import NPZ_READ_ERRORS

__all__ = ["ContextBank", "TravelScore", "SpeedScore", "FloorSpeedScore", "Gate", "build_bank", "calibrate_gate",
           "held_out_ratios", "gated_ratio", "BLEND_WEIGHTS", "OOD_FILE", "gate_note", "save_gate", "load_gate",
           "run_gate", "load_gate_array", "optional_gate_arrays"]

OOD_FILE = "ood.npz"                              # the bank and gate in a run folder / shipped weights folder
BLEND_WEIGHTS = (0.0, 0.25, 0.5, 0.75, 1.0)       # weights of the learned fill at which calibration scores windows


@dataclasses.dataclass
class ContextBank:
    """Training contexts, standardised and projected: ``mean`` / ``scale`` (D,), ``basis`` (D, P),
    ``codes`` (N, P) float32, ``k`` neighbours, ``ref`` the training contexts' median leave-one-out k-NN distance."""
    mean: np.ndarray
    scale: np.ndarray
    basis: np.ndarray
    codes: np.ndarray
    k: int
    ref: float

    def project(self, desc) -> np.ndarray:
        """(B, D) contexts -> (B, P) codes."""
        d = np.asarray(desc, np.float64)
        if d.ndim != 2 or d.shape[1] != self.mean.shape[0]:
            raise ValueError(f"contexts of shape {d.shape}: this bank holds {self.mean.shape[0]}-number contexts")
        return ((d - self.mean) / self.scale) @ self.basis

    def knn_distance(self, codes, exclude_self: bool = False) -> np.ndarray:
        """(B, P) codes -> (B,) mean Euclidean distance to the k nearest bank codes (chunks of 512)."""
        bank = self.codes.astype(np.float64)
        b2 = np.sum(bank ** 2, axis=1)
        out = []
        for lo in range(0, len(codes), 512):
            c = np.asarray(codes[lo:lo + 512], np.float64)
            d2 = np.maximum(np.sum(c ** 2, 1)[:, None] - 2 * c @ bank.T + b2[None], 0.0)
            kk = self.k + 1 if exclude_self else self.k
            part = np.sort(np.partition(d2, kk - 1, axis=1)[:, :kk], axis=1)
            out.append(np.sqrt(part[:, 1:] if exclude_self else part).mean(1))
        return np.concatenate(out) if out else np.zeros(0)

    def score(self, desc) -> np.ndarray:
        """(B, D) contexts -> (B,) out-of-distribution score (about 1 for training-like contexts)."""
        return self.knn_distance(self.project(desc)) / self.ref

    def arrays(self, prefix: str = "bank_") -> dict:
        return {f"{prefix}{k}": np.asarray(v) for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "bank_") -> "ContextBank":
        a = {f.name: arrays[f"{prefix}{f.name}"] for f in dataclasses.fields(cls)}
        return cls(a["mean"], a["scale"], a["basis"], a["codes"], int(a["k"]), float(a["ref"]))


@dataclasses.dataclass
class TravelScore:
    """A score from how far the keyframes say the character travels: ``1 / (1 + speed / c)`` with ``speed`` the
    root's floor distance between the two keyframes per generated frame (data units per frame), read from a
    keyframe context whose first ``2 J 3`` numbers are both poses' FK positions (root first) and whose last is
    the number of frames / 30 (:func:`inbetween_jax.models.scvae.gate.keyframe_context`).  1 for keyframes in
    place, 0.5 at ``c`` per frame, toward 0 for fast travel: the S-CVAE's training motion is mostly locomotion,
    and on held-out subjects it loses to Slerp exactly where the keyframes imply little travel."""
    num_joints: int
    c: float = 1.0

    def score(self, desc) -> np.ndarray:
        d = np.asarray(desc, np.float64)
        p = d[:, :-1].reshape(len(d), 2, self.num_joints, 3)
        speed = np.linalg.norm((p[:, 1, 0] - p[:, 0, 0])[:, [0, 2]], axis=-1) / (d[:, -1] * 30.0 + 1.0)
        return 1.0 / (1.0 + speed / self.c)

    def arrays(self, prefix: str = "travel_") -> dict:
        return {f"{prefix}num_joints": np.int64(self.num_joints), f"{prefix}c": np.float64(self.c)}


@dataclasses.dataclass
class SpeedScore:
    """A score from how fast the context moves: ``1 / (1 + v / c)`` with ``v`` the first number of each context
    (the mean joint speed at the last known frame, cm per frame: :func:`inbetween_jax.models.interaction.gate.
    window_context`).  1 for a still context, 0.5 at ``c``, toward 0 for fast motion: on the validation take the
    interaction model loses to interpolation where the dancers barely move, and a k-NN distance to the training
    takes does not predict where it loses (docs/results/gate.md)."""
    c: float = 1.0

    def score(self, desc) -> np.ndarray:
        return 1.0 / (1.0 + np.asarray(desc, np.float64)[:, 0] / self.c)

    def arrays(self, prefix: str = "speed_") -> dict:
        return {f"{prefix}c": np.float64(self.c)}


@dataclasses.dataclass
class FloorSpeedScore:
    """A score from how fast the root moves over the floor at the known frames beside a gap: ``1 / (1 + v / c)``,
    ``v`` the mean floor speed (data units per frame) over the context's frames.  It reads a CAE gap context
    (:func:`inbetween_jax.models.cae.gate.gap_context`: ``frames`` columns of ``dims`` normalised features, then
    the gap length): the rows ``rows`` of each column are the root's floor velocity, normalised with ``mean`` /
    ``std`` (2,).  1 beside a body standing still, 0.5 at ``c`` per frame: a CAE whose training motion is mostly
    locomotion may help where the body travels and harm motion in place (docs/results/gate.md)."""
    dims: int
    frames: int
    rows: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    c: float = 1.0

    def speed(self, desc) -> np.ndarray:
        """(B,) mean floor speed of the contexts (B, frames * dims + 1)."""
        d = np.asarray(desc, np.float64)
        cols = d[:, :-1].reshape(len(d), self.frames, self.dims)[:, :, np.asarray(self.rows, int)]
        v = cols * np.asarray(self.std, np.float64) + np.asarray(self.mean, np.float64)
        return np.linalg.norm(v, axis=-1).mean(1)

    def score(self, desc) -> np.ndarray:
        return self.score_of_speed(self.speed(desc))

    def score_of_speed(self, speed) -> np.ndarray:
        """The score of floor speeds already measured (data units per frame, any shape)."""
        return 1.0 / (1.0 + np.asarray(speed, np.float64) / self.c)

    def arrays(self, prefix: str = "floor_") -> dict:
        return {f"{prefix}{k}": np.asarray(v) for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "floor_") -> "FloorSpeedScore":
        a = {f.name: arrays[f"{prefix}{f.name}"] for f in dataclasses.fields(cls)}
        return cls(int(a["dims"]), int(a["frames"]), np.asarray(a["rows"], np.int64),
                   np.asarray(a["mean"], np.float64), np.asarray(a["std"], np.float64), float(a["c"]))


def build_bank(desc, dims: int = 32, k: int = 4, max_items: int = 4000, seed: int = 0) -> ContextBank:
    """A :class:`ContextBank` of (N, D) training contexts: standardised per number, the first ``dims`` principal
    components kept (float16-safe codes), at most ``max_items`` contexts (a seeded random subset)."""
    d = np.asarray(desc, np.float64)
    if d.ndim != 2 or len(d) < k + 2:
        raise ValueError(f"need at least {k + 2} training contexts, got shape {d.shape}")
    if len(d) > max_items:
        d = d[np.random.default_rng(seed).choice(len(d), max_items, replace=False)]
    mean, scale = d.mean(0), d.std(0) + 1e-3
    z = (d - mean) / scale
    _, _, vt = np.linalg.svd(z - z.mean(0), full_matrices=False)
    basis = vt[:min(dims, vt.shape[0])].T
    bank = ContextBank(mean, scale, basis, (z @ basis).astype(np.float32), int(k), 1.0)
    loo = bank.knn_distance(bank.codes, exclude_self=True)
    bank.ref = float(np.median(loo)) or 1.0
    return bank


@dataclasses.dataclass(frozen=True)
class Gate:
    """Weight of the learned fill: 1 at score <= lo, 0 at score >= hi, linear between (``enabled=False``: 1)."""
    lo: float
    hi: float
    enabled: bool = True

    def weight(self, score) -> np.ndarray:
        s = np.asarray(score, np.float64)
        if not self.enabled:
            return np.ones_like(s)
        return np.clip((self.hi - s) / max(self.hi - self.lo, 1e-9), 0.0, 1.0)


def gated_ratio(ratios_at, weights) -> np.ndarray:
    """Each window's error ratio at its gate weight, linearly interpolated between the ratios measured at
    :data:`BLEND_WEIGHTS`.  ratios_at (B, len(BLEND_WEIGHTS)); weights (B,) -> (B,)."""
    r = np.asarray(ratios_at, np.float64)
    return np.array([np.interp(w, BLEND_WEIGHTS, row) for w, row in zip(np.asarray(weights, np.float64), r)])


EPS = 1e-9     # ratios of equal errors come out 1 +- a few ulp: the limits compare with this slack


def calibrate_gate(scores, ratios_at, p90_max: float = 1.05, worst_max: float = 1.5, groups=None,
                   scale=None) -> tuple:
    """Choose ``(lo, hi)`` on validation windows: the lowest mean gated ratio among the thresholds whose 90th
    percentile is at most ``p90_max``, maximum at most ``worst_max`` and (with ``groups``, a label per window,
    e.g. activity and length) every group's mean at most 1 (if none qualifies: the lowest 90th percentile).
    scores (B,); ratios_at (B, len(BLEND_WEIGHTS)): each window's error ratio to its base with the learned fill
    blended in at each weight; ``scale`` (B,), when given, multiplies each window's gate weight (a bound the
    model applies on top of the gate).  Returns ``(Gate, summary dict)``."""
    s = np.asarray(scores, np.float64)
    scale = np.ones_like(s) if scale is None else np.asarray(scale, np.float64)
    labels = np.asarray(["all"] * len(s) if groups is None else [str(g) for g in groups])
    members = [labels == g for g in np.unique(labels)]
    qs = np.quantile(s, [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0])
    best, best_key = None, None
    candidates = [(lo, lo * f) for lo in qs for f in (1.0001, 1.1, 1.25, 1.5, 2.0, 3.0)]
    candidates += [(np.inf, np.inf)]                         # never gate (the learned fill everywhere)
    for lo, hi in candidates:
        g = Gate(float(lo), float(hi), enabled=np.isfinite(lo))
        r = gated_ratio(ratios_at, g.weight(s) * scale)
        p90, worst, mean = np.quantile(r, 0.9), r.max(), r.mean()
        group_worst = max(float(r[m].mean()) for m in members)
        ok = p90 <= p90_max + EPS and worst <= worst_max + EPS and group_worst <= 1.0 + EPS
        key = (0 if ok else 1, mean if ok else p90)
        if best_key is None or key < best_key:
            best, best_key = (g, {"mean": float(mean), "p90": float(p90), "max": float(worst),
                                  "worst_group_mean": group_worst,
                                  "meets_limits": bool(ok), "windows": int(len(s))}), key
    return best


def held_out_ratios(scores, ratios_at, groups, units) -> np.ndarray:
    """(B,) each window's gated ratio with the thresholds :func:`calibrate_gate` chooses on the windows of every
    other unit (e.g. subject; ``units`` (B,) a label per window): how much the choice depends on the unit scored."""
    s, units = np.asarray(scores, np.float64), np.asarray(units)
    ratios_at, groups = list(ratios_at), list(groups)
    held = np.zeros(len(s))
    for u in sorted(set(units.tolist())):
        out = units == u
        gate = calibrate_gate(s[~out], [x for x, o in zip(ratios_at, out) if not o],
                              groups=[x for x, o in zip(groups, out) if not o])[0]
        held[out] = gated_ratio([x for x, o in zip(ratios_at, out) if o], gate.weight(s[out]))
    return held


def gate_note(score: float, weight: float, base: str) -> str:
    """The line the CLI prints about the out-of-distribution gate (:mod:`inbetween_jax.models.ood`)."""
    if weight < 0.5:
        return (f"outside what the network learned (out-of-distribution score {score:.2f}): the fill falls "
                f"mostly back to its base, {base} (learned part kept at {weight:.2f})")
    return f"out-of-distribution score {score:.2f}: learned fill kept at {weight:.2f} over its base ({base})"


def save_gate(run_dir: str, bank, gate: Gate, summary: dict | None = None, arrays: dict | None = None) -> str:
    """Write ``ood.npz`` (the scorer -- a :class:`ContextBank`, :class:`TravelScore`, :class:`SpeedScore` or
    :class:`FloorSpeedScore` -- + gate thresholds + the calibration summary's numbers + a model's own ``arrays``)
    atomically."""
    path = os.path.join(run_dir, OOD_FILE)
    extra = {f"summary_{k}": np.asarray(v) for k, v in (summary or {}).items()
             if isinstance(v, (int, float, bool, np.floating, np.integer))}
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, **bank.arrays(), gate_lo=np.float64(gate.lo), gate_hi=np.float64(gate.hi), **extra,
                        **{k: np.asarray(v) for k, v in (arrays or {}).items()})
    os.replace(tmp, path)
    return path


def _read_ood(run_dir: str, read):
    """``read(z)`` of the open ``run_dir/ood.npz``, or None when the folder has none; an unreadable file (or a
    missing array ``read`` needs) is one line naming it (RunError)."""
    from inbetween_jax.train.run import RunError
    path = os.path.join(run_dir, OOD_FILE)
    if not os.path.exists(path):
        return None
    try:
        with np.load(path) as z:
            return read(z)
    except (*NPZ_READ_ERRORS, KeyError) as e:
        raise RunError(f"{path}: not a readable out-of-distribution gate ({type(e).__name__}: {e})") from None


def load_gate(run_dir: str):
    """``(ContextBank, Gate)`` from ``run_dir/ood.npz``, or None when the folder has none.

    Raises:
        RunError: the file exists but cannot be read (one line).
    """
    def read(z):
        if "travel_c" in z.files:
            scorer = TravelScore(int(z["travel_num_joints"]), float(z["travel_c"]))
        elif "speed_c" in z.files:
            scorer = SpeedScore(float(z["speed_c"]))
        elif "floor_c" in z.files:
            scorer = FloorSpeedScore.from_arrays(z)
        else:
            scorer = ContextBank.from_arrays(z)
        return scorer, Gate(float(z["gate_lo"]), float(z["gate_hi"]))
    return _read_ood(run_dir, read)


def load_gate_array(run_dir: str, key: str, why: str) -> np.ndarray:
    """A model's own array ``key`` of ``run_dir/ood.npz`` (written by its calibration).

    Raises:
        RunError: the file or the array is missing or unreadable; ``why`` names the setting that needs it.
    """
    from inbetween_jax.train.run import RunError
    path = os.path.join(run_dir, OOD_FILE)
    try:
        with np.load(path) as z:
            return np.asarray(z[key], np.float64)
    except (*NPZ_READ_ERRORS, KeyError) as e:
        raise RunError(f"{path}: {why} needs '{key}', which it does not hold ({type(e).__name__}; recalibrate with "
                       "`inbetween calibrate-gate RUN_DIR`)") from None


def optional_gate_arrays(run_dir: str, prefix: str, required: tuple = ()) -> dict | None:
    """The arrays of ``run_dir/ood.npz`` whose names start with ``prefix`` (what a calibration added beside the
    gate: the S-CVAE's in-clip thresholds, the CAE's k-NN cap), or None when the file or any of ``required``
    is absent (a gate calibrated before they existed).

    Raises:
        RunError: the file exists but cannot be read (one line).
    """
    def read(z):
        if not all(k in z.files for k in required):
            return None
        return {k: np.asarray(z[k]) for k in z.files if k.startswith(prefix)}
    return _read_ood(run_dir, read)


def run_gate(run_dir: str, enabled: bool):
    """The run folder's ``(scorer, Gate)`` when ``model.ood_gate`` is on (``enabled``), else None.

    Raises:
        RunError: the switch is on but the folder holds no readable ``ood.npz`` (one line).
    """
    if not enabled:
        return None
    from inbetween_jax.train.run import RunError
    gate = load_gate(run_dir)
    if gate is None:
        raise RunError(f"{run_dir}: model.ood_gate is on but the folder holds no {OOD_FILE} (calibrate it with "
                       "`inbetween calibrate-gate RUN_DIR`)")
    return gate
