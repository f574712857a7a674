"""A motion bank of real two-person capture: nearest-neighbour in-betweens and motion texture.

Beyond the paper; inference only (the trained network is the same with or without), all off unless a run's
config turns them on (``model.bank_k``, ``model.bank_weight``, ``model.texture_sigma``,
``model.texture_gain``).  The bank holds the training takes' world features (``bank.npz`` in a run or shipped
weights folder, written by ``inbetween build-bank``); a query is a test window's context and keyposes,
each character in its keyframe space as :func:`~.features.keyframe_sample` builds them.

* :func:`knn_inbetween` -- the ``k`` bank windows of the same gap length whose last context frames (positions
  and velocity) and keyposes (positions), both characters, lie nearest to the query's (with
  ``model.bank_pair_weight`` > 0 also the two characters' placement at the keyframe, :func:`pair_features`: each
  character's features live in its own keyframe space and say nothing of where the partner stands); each is
  warped (Witkin & Popovic 1995) to start at the query's last context frame and end at its keypose (the two end
  offsets blended linearly over the gap) and the ``k`` are averaged.  :func:`apply_bank` blends that with the
  network's rollout (``bank_weight``).
* :func:`arrival_gaps` -- the gap a rollout takes (the frames before the stop rule's threshold is first met), so
  that with a guessed gap (``model.bank_guessed``) the bank follows the network's timing, not the guess.
* :func:`texture` -- motion texturing (Pullen & Bregler 2002): the high-frequency band of the nearest window's
  joint positions (the window minus its Gaussian low-pass of ``texture_sigma`` frames) is added to the
  in-between, faded in and out over :data:`FADE` frames at either end so the context and keypose stay continuous.
  Rotations are left alone, and so are feet near the floor (:func:`apply_bank`).  The network's rollouts are smooth
  (they move at about 60 % of the capture's joint speed); the interaction classifier tells them from capture by this
  band (docs/results/interaction.md, tenth round).
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from inbetween_jax.data.filters import gaussian_lowpass
from inbetween_jax.errors import NPZ_READ_ERRORS, UserError
from inbetween_jax.metrics.foot import SKATING_HEIGHT_CM
from inbetween_jax.models.interaction.features import keyframe_sample

__all__ = ["BANK_FILE", "SWITCHES", "MATCH_FRAMES", "FADE", "MotionBank", "gaussian_lowpass", "match_features",
           "pair_features", "knn_inbetween", "texture", "apply_bank", "arrival_gaps", "bank_enabled", "foot_indices",
           "ease_into_keypose"]

BANK_FILE = "bank.npz"
SWITCHES = ("model.bank_k", "model.bank_weight", "model.texture_sigma", "model.texture_gain",
            "model.bank_guessed", "model.bank_sample_weight", "model.bank_pair_weight",
            "model.bank_sample_gated")        # inference only; the last acts in .gate (samples s >= 1 ungated)
MATCH_FRAMES = 3          # last context frames whose joint positions are matched
VELOCITY_WEIGHT = 5.0     # weight of the last context frame's velocity (m / frame) in the match
FADE = 4                  # texture fade-in / fade-out frames at either end of the gap
CACHED_LENGTHS = 32       # gap lengths whose match features a bank keeps


@dataclasses.dataclass
class MotionBank:
    """Training takes for retrieval.  takes: per take (2, T, J, 9) float32 world features (file units);
    forward_axis: (3,) the root's local facing axis; pos_scale: file units -> model units (metres);
    stride: frames between bank windows.  Their match features (:meth:`index`) are cached per gap length."""
    takes: tuple
    names: tuple
    forward_axis: np.ndarray
    pos_scale: float
    stride: int = 2
    _cache: dict = dataclasses.field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_pairs(cls, pairs, pos_scale: float, stride: int = 2) -> "MotionBank":
        """A bank of :class:`~.data.PairedMotion` s (one skeleton and facing axis)."""
        if not pairs:
            raise UserError("motion bank: no training pairs to build it from")
        return cls(tuple(np.asarray(p.feats, np.float32) for p in pairs), tuple(p.name for p in pairs),
                   np.asarray(pairs[0].forward_axis, np.float64), float(pos_scale), int(stride))

    @property
    def num_frames(self) -> int:
        return int(sum(t.shape[1] for t in self.takes))

    def save(self, path: str) -> None:
        """Write ``path`` (npz) atomically."""
        arrays = {f"take_{i:03d}": t for i, t in enumerate(self.takes)}
        tmp = path + ".tmp.npz"
        np.savez_compressed(tmp, names=np.asarray(self.names), forward_axis=self.forward_axis,
                            pos_scale=np.float64(self.pos_scale), stride=np.int64(self.stride), **arrays)
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: str) -> "MotionBank":
        """Read a bank written by :meth:`save`.  Raises UserError (one line) on a missing or malformed file."""
        try:
            with np.load(path, allow_pickle=False) as z:
                keys = sorted(k for k in z.files if k.startswith("take_"))
                takes = tuple(np.asarray(z[k], np.float32) for k in keys)
                bank = cls(takes, tuple(str(n) for n in z["names"]), np.asarray(z["forward_axis"], np.float64),
                           float(z["pos_scale"]), int(z["stride"]))
        except (*NPZ_READ_ERRORS, KeyError) as e:
            raise UserError(f"{path}: not a readable motion bank ({e})") from None
        if not takes or any(t.ndim != 4 or t.shape[0] != 2 or t.shape[-1] != 9 for t in takes):
            raise UserError(f"{path}: not a motion bank (expected takes of shape (2, T, J, 9))")
        return bank

    def index(self, n_input: int, gap: int) -> np.ndarray:
        """Match features (N, D) of every bank window of ``n_input`` context frames, ``gap`` frames and the
        keyframe (stride :attr:`stride`), cached for the :data:`CACHED_LENGTHS` gap lengths used last (about 5 MB
        each for the shipped bank); only the matched frames are transformed."""
        return self._indexed(n_input, gap)[0]

    def pair_index(self, n_input: int, gap: int) -> np.ndarray:
        """:func:`pair_features` (N, 4) of the same windows as :meth:`index`, in its order."""
        return self._indexed(n_input, gap)[1]

    def _indexed(self, n_input: int, gap: int) -> tuple:
        key = (n_input, gap)
        if key in self._cache:
            self._cache[key] = self._cache.pop(key)                       # most recently used last
        else:
            while len(self._cache) >= CACHED_LENGTHS:
                self._cache.pop(next(iter(self._cache)))
            starts = self._starts(n_input, gap)
            lead = n_input - MATCH_FRAMES
            parts = [keyframe_sample(self.takes[i], s + lead, MATCH_FRAMES, gap + MATCH_FRAMES, self.forward_axis)
                     for i, s in starts]
            ctx = np.stack([p["x"] for p in parts]).astype(np.float32)
            kp = np.stack([p["keypose"] for p in parts]).astype(np.float32)
            rel_t = np.stack([p["rel_t"] for p in parts]) * self.pos_scale
            self._cache[key] = (match_features(ctx * self._scale, kp * self._scale),
                                pair_features(np.stack([p["rel_R"] for p in parts]), rel_t))
        return self._cache[key]

    def gather(self, n_input: int, gap: int, idx) -> np.ndarray:
        """Bank windows ``idx`` (any shape) of :meth:`index`'s order in each character's keyframe space,
        positions scaled: (*idx.shape, 2, n_input + gap + 1, J, 9)."""
        idx = np.asarray(idx)
        starts = self._starts(n_input, gap)
        length = n_input + gap + 1
        x = np.stack([keyframe_sample(self.takes[starts[i][0]], starts[i][1], length, length - 1,
                                      self.forward_axis)["x"] for i in idx.reshape(-1)]).astype(np.float32)
        return (x * self._scale).reshape(idx.shape + x.shape[1:])

    def max_gap(self, n_input: int) -> int:
        """The longest gap whose windows (``n_input`` context frames, the gap, the keyframe) the bank holds."""
        return max(t.shape[1] for t in self.takes) - n_input - 1

    @property
    def _scale(self) -> np.ndarray:
        return np.array([self.pos_scale] * 3 + [1.0] * 6, np.float32)

    def _starts(self, n_input: int, gap: int) -> list:
        """[(take, first frame)] of every window of n_input + gap + 1 frames."""
        length = n_input + gap + 1
        starts = [(i, s) for i, t in enumerate(self.takes) for s in range(0, t.shape[1] - length + 1, self.stride)]
        if not starts:
            raise UserError(f"motion bank: no take is long enough for a {gap}-frame gap "
                            f"({length} frames with the context)")
        return starts


def match_features(context, keypose) -> np.ndarray:
    """context (B, 2, >= MATCH_FRAMES, J, >= 3) key-space frames ending at the last context frame, keypose
    (B, 2, J, >= 3) -> (B, D) the vector nearest neighbours are found by (positions in model units)."""
    c = np.asarray(context, np.float32)[..., :3]
    vel = (c[:, :, -1] - c[:, :, -2]) * VELOCITY_WEIGHT
    parts = (c[:, :, -MATCH_FRAMES:], vel, np.asarray(keypose, np.float32)[..., :3])
    return np.concatenate([p.reshape(len(c), -1) for p in parts], 1)


def pair_features(rel_R, rel_t) -> np.ndarray:
    """How the two characters stand at the keyframe: character B's keyframe-space origin in character A's keyframe
    space (x, z; model units) and the cosine and sine of B's heading there.  rel_R (B, 2, 3, 3), rel_t (B, 2, 3):
    the maps between the characters' keyframe spaces (:func:`~.features.keyframe_sample`) -> (B, 4)."""
    R, t = np.asarray(rel_R, np.float32)[:, 1], np.asarray(rel_t, np.float32)[:, 1]
    return np.concatenate([t[:, [0, 2]], R[:, 0, [0, 2]]], 1)


def _nearest(bank: MotionBank, context, keypose, gap: int, k: int, rel=None, pair_weight: float = 0.0) -> np.ndarray:
    """-> the k nearest bank windows, nearest first: (B, k, 2, n_input + gap + 1, J, 9).  With ``pair_weight`` > 0
    the distance also counts ``pair_weight^2`` times the squared distance of :func:`pair_features` (``rel``: the
    query's ``(rel_R, rel_t)``, model units)."""
    n = context.shape[2]
    feats = bank.index(n, gap)
    f = match_features(context, keypose)
    d2 = (f ** 2).sum(1)[:, None] + (feats ** 2).sum(1)[None] - 2.0 * f @ feats.T
    if pair_weight > 0:
        if rel is None:
            raise ValueError("model.bank_pair_weight needs the query's rel_R and rel_t")
        q, pb = pair_features(*rel), bank.pair_index(n, gap)
        d2 = d2 + pair_weight ** 2 * ((q[:, None] - pb[None]) ** 2).sum(-1)
    k = min(k, len(feats))
    idx = np.argpartition(d2, k - 1, axis=1)[:, :k] if k < len(feats) else np.tile(np.arange(k), (len(f), 1))
    order = np.argsort(np.take_along_axis(d2, idx, 1), 1)
    return bank.gather(n, gap, np.take_along_axis(idx, order, 1))


def knn_inbetween(bank: MotionBank, context, keypose, gap: int, k: int, rel=None,
                  pair_weight: float = 0.0) -> np.ndarray:
    """Mean of the ``k`` nearest bank windows, each warped onto the query's last context frame and keypose.

    context (B, 2, n_input, J, 9), keypose (B, 2, J, 9) in key space (model units); rel / pair_weight: as
    :func:`_nearest` -> (B, 2, gap, J, 9)."""
    context, keypose = np.asarray(context, np.float32), np.asarray(keypose, np.float32)
    return _warped_mean(_nearest(bank, context, keypose, gap, k, rel, pair_weight), context, keypose, gap)


def texture(bank: MotionBank, context, keypose, gap: int, sigma: float, rel=None,
            pair_weight: float = 0.0) -> np.ndarray:
    """The nearest bank window's high-frequency joint-position band over the gap, faded in and out:
    (B, 2, gap, J, 9), zero in the rotation channels."""
    context = np.asarray(context, np.float32)
    nearest = _nearest(bank, context, np.asarray(keypose, np.float32), gap, 1, rel, pair_weight)[:, 0]
    return _faded_band(nearest, context.shape[2], gap, sigma)


def _warped_mean(near, context, keypose, gap: int) -> np.ndarray:
    """near (B, k, 2, n + gap + 1, J, 9) bank windows -> the mean of them warped onto the query's ends."""
    n = context.shape[2]
    t = (np.arange(1, gap + 1, dtype=np.float32) / (gap + 1))[None, None, :, None, None]
    out = np.zeros(context.shape[:2] + (gap,) + context.shape[3:], np.float32)
    for j in range(near.shape[1]):
        c = near[:, j]
        start = (context[:, :, -1] - c[:, :, n - 1])[:, :, None]
        end = (keypose - c[:, :, -1])[:, :, None]
        out += c[:, :, n:n + gap] + (1 - t) * start + t * end
    return out / near.shape[1]


def _faded_band(c, n: int, gap: int, sigma: float) -> np.ndarray:
    """c (B, 2, n + gap + 1, J, 9) one bank window per query -> its position band above a Gaussian low-pass over
    the gap, faded in and out over :data:`FADE` frames; rotation channels zero."""
    band = np.zeros(c.shape[:2] + (gap,) + c.shape[3:], np.float32)
    band[..., :3] = (c[..., :3] - gaussian_lowpass(c[..., :3], sigma, 2))[:, :, n:n + gap]
    fade = np.ones(gap, np.float32)
    m = min(FADE, gap // 2)
    ramp = np.arange(1, m + 1, dtype=np.float32) / (m + 1)
    if m:
        fade[:m], fade[gap - m:] = ramp, ramp[::-1]
    return band * fade[None, None, :, None, None]


def foot_indices(skeleton) -> tuple:
    """The skeleton's foot joints (:meth:`~inbetween_jax.data.skeleton.Skeleton.foot_joints`), or () when there
    is no skeleton or its feet are not found by name (texture then reaches the feet too)."""
    try:
        return tuple(sorted(set(skeleton.foot_joints()))) if skeleton is not None else ()
    except KeyError:
        return ()


def arrival_gaps(frames, keypose, threshold_m: float, pos_scale: float, lo: int = 1) -> np.ndarray:
    """The gap each rollout takes: the number of frames before the first one at which both characters' mean
    joint distance to their keyposes is below ``threshold_m`` metres (the rollout's frame count when it never
    is), at least ``lo``.  With the stop rule's threshold (``model.stop_threshold``) a blend over this gap keeps
    the frame at which the rollout stops.

    frames (B, 2, F, J, >= 3), keypose (B, 2, J, >= 3) in model units; pos_scale: ``data.pos_scale``; distances
    as the evaluation's stop-rule statistics measure them
    (:func:`~inbetween_jax.evaluation.interaction.keypose_distance_m`).  -> (B,) int."""
    from inbetween_jax.evaluation.interaction import keypose_distance_m
    frames = np.asarray(frames, np.float64)
    near = keypose_distance_m(frames, np.asarray(keypose, np.float64), pos_scale) < threshold_m     # (B, F)
    return np.maximum(np.where(near.any(-1), near.argmax(-1), frames.shape[2]), lo).astype(int)


def bank_enabled(model_cfg) -> bool:
    """Whether a model config asks for the bank at inference."""
    return (model_cfg.bank_k > 0 and model_cfg.bank_weight > 0 or model_cfg.texture_sigma > 0
            or model_cfg.bank_sample_weight > 0)


def apply_bank(bank: MotionBank, model_cfg, frames, context, keypose, gaps, feet=(), rel=None) -> np.ndarray:
    """Rollouts with the bank's in-between blended in and texture added over each window's gap.

    frames (S, B, 2, F, J, 9) rollouts in key space (model units, y up); context (B, 2, n_input, J, 9); keypose
    (B, 2, J, 9); gaps (B,) the gap each rollout aims at; feet: foot joint indices, whose texture is faded out
    near the floor: its weight is 0 where the foot, with or without texture, is at or below the foot-skating
    height H = 2.5 cm and 1 from 2 H, so a foot the rollout holds above H is never textured below it.  Frames
    past a window's gap are left as they are.  With ``model.bank_sample_weight`` > 0 and S > 1 (the sampled
    mode), sample 0 is as above and sample s >= 1 blends in one bank window, the s-th nearest, warped, at that
    weight, with that window's texture on the rest (``texture_gain`` x (1 - weight)): the samples differ by real
    captured motion.  rel: the query's ``(rel_R, rel_t)`` (B, 2, 3, 3) / (B, 2, 3), needed with
    ``model.bank_pair_weight`` > 0 (the characters' placement at the keyframe joins the match).
    -> (S, B, 2, F, J, 9)."""
    out = np.array(frames, np.float32)
    gaps = np.asarray(gaps).astype(int)
    w, k = float(model_cfg.bank_weight), int(model_cfg.bank_k)
    blend, textured = k > 0 and w > 0, model_cfg.texture_sigma > 0
    ws = float(model_cfg.bank_sample_weight) if out.shape[0] > 1 else 0.0
    context, keypose = np.asarray(context, np.float32), np.asarray(keypose, np.float32)
    floor = SKATING_HEIGHT_CM * bank.pos_scale
    for g in np.unique(gaps):
        sel = np.flatnonzero(gaps == g)
        n = min(int(g), out.shape[3])
        if n <= 0 or not (blend or textured or ws > 0):
            continue
        ctx, kp = context[sel], keypose[sel]
        rel_sel = None if rel is None else tuple(np.asarray(r)[sel] for r in rel)
        near = _nearest(bank, ctx, kp, int(g), max(k if blend else 1, out.shape[0] - 1 if ws > 0 else 0),
                        rel_sel, float(model_cfg.bank_pair_weight))
        pre = out[:, sel, :, :n].copy() if ws > 0 else None       # the rollouts the sampled mode blends from
        if blend:
            mean = _warped_mean(near[:, :k], ctx, kp, int(g))[:, :, :n]
            out[:, sel, :, :n] = (1 - w) * out[:, sel, :, :n] + w * mean[None]
        if textured:
            band = model_cfg.texture_gain * _faded_band(near[:, 0], ctx.shape[2], int(g),
                                                        model_cfg.texture_sigma)[:, :, :n]
            out[:, sel, :, :n] += _foot_safe(np.repeat(band[None], out.shape[0], 0), out[:, sel, :, :n], feet, floor)
        for s in range(1, out.shape[0] if ws > 0 else 1):          # the sampled mode: one window per sample
            j = (s - 1) % near.shape[1]
            one = _warped_mean(near[:, j:j + 1], ctx, kp, int(g))[:, :, :n]
            out[s, sel, :, :n] = (1 - ws) * pre[s] + ws * one
            if textured and ws < 1:    # the window brings its own band at weight ws: texture the rest
                band = (1 - ws) * model_cfg.texture_gain * _faded_band(near[:, j], ctx.shape[2], int(g),
                                                                     model_cfg.texture_sigma)[:, :, :n]
                out[s, sel, :, :n] += _foot_safe(band[None], out[s:s + 1, sel, :, :n], feet, floor)[0]
    return out


def _foot_safe(add, base, feet, floor: float) -> np.ndarray:
    """Texture ``add`` (S, b, 2, n, J, 9) with the foot joints' part faded out where the foot of ``base`` (same
    shape), with or without the texture, is within 2 ``floor`` of the floor (:func:`apply_bank`)."""
    if not len(feet):
        return add
    add = np.array(add, np.float32)
    foot = list(feet)
    h = base[..., foot, 1]
    low = np.minimum(h, h + add[..., foot, 1]) / floor                  # the lower of base and textured
    add[..., foot, :3] *= np.clip(low - 1.0, 0.0, 1.0)[..., None]
    return add


def ease_into_keypose(frames, keypose, gaps, ease: int) -> np.ndarray:
    """Rollouts whose last ``ease`` frames before each window's keypose take up the jump onto it: with ``x`` the
    positions, ``n`` the gap and ``e = key - (2 x[n-1] - x[n-2])`` the keypose's distance from where the motion
    was heading, frame ``n - ease + i`` moves by ``s(i) e`` (``s``: smoothstep from 0 to 1 at frame ``n - 1``),
    so the step onto the key equals the rollout's own last step (``x[n-1] - x[n-2]``) instead of a snap.  Positions only
    (the first 3 of the 9 numbers); frames from the gap on are left as they are.

    frames (S, B, 2, F, J, 9); keypose (B, 2, J, 9); gaps (B,) ints.  -> (S, B, 2, F, J, 9) float32."""
    out = np.array(frames, np.float32)
    kp = np.asarray(keypose, np.float32)
    for b, g in enumerate(np.asarray(gaps).astype(int)):
        n = min(int(g), out.shape[3])
        m = min(int(ease), n - 2)
        if m < 1:
            continue
        x = out[:, b, :, :n, :, :3]                                            # (S, 2, n, J, 3)
        e = kp[None, b, :, :, :3] - (2 * x[:, :, -1] - x[:, :, -2])            # (S, 2, J, 3)
        t = np.arange(1, m + 1) / m
        s = (3 * t ** 2 - 2 * t ** 3)[:, None, None]                           # 0 .. 1 at frame n - 1
        out[:, b, :, n - m:n, :, :3] += s[None, None] * e[:, :, None]
    return out

