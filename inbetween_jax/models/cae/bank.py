"""Motion matching for the CAE's gaps inside a file: the nearest training window, offset-blended onto the known
frames, where one lies near enough.

Beyond the paper; inference only (the trained network is the same with or without), off unless a run's config
turns it on (``model.match_k`` > 0).  The bank is the S-CVAE's :class:`~inbetween_jax.models.scvae.bank.
TransitionBank` format (``bank.npz`` in the run or shipped weights folder, written by ``inbetween build-bank``):
the training clips' local rotations and root positions, turned into the CAE's features (body-frame joint
positions and root velocities, normalised with the run's statistics) when loaded.

For a gap ``[a, b)`` of a file, :func:`match_gap` compares the gap's context -- the feature columns of the known
frames ``a - 1, a - 4, a - 8`` and ``b, b + 3, b + 7`` (:func:`~inbetween_jax.models.cae.gate.gap_context`) --
and the root's floor displacement and turn from ``a - 1`` to ``b`` (in the body frame at ``a - 1``, metres and
radians) with every training window of the same length.  The ``k`` nearest (mean squared difference per context
number, displacement included with weight ``match_disp``) are each offset-blended onto the known frames (the
difference at ``a - 1`` fading out linearly over the gap and the difference at ``b`` fading in; Kovar et al.'s
transition blending) and averaged.  A gate on that distance, ``w = clip((hi - d) / (hi - lo), 0, 1)``
(``match_lo`` / ``match_hi``; with ``match_speed_scale`` > 0 on the distance over ``1 + root speed beside the gap /
scale``, :func:`gate_distance`), blends the match over the gap's fill: ``fill + w (match - fill)``.  A match whose
body departs from the fill by more than ``match_departure`` times the body's own travel beside the gap
(:func:`departure`) is not used at all: the distance alone let matches that walk through a gap where the body
stands still (a jump in place) through when the thresholds were chosen without that subject.  Both are chosen on
the validation subjects by ``experiments/cae_motion_match.py``.  Why: the network's fills stay at its Hermite base on
motion it never saw (docs/results/gate.md), which glides instead of stepping; a walking window from the training
motion, matched at both ends, steps.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from inbetween_jax.errors import UserError

__all__ = ["BANK_FILE", "SWITCHES", "MatchBank", "match_enabled", "match_candidates", "match_gap", "departure",
           "match_weight", "speed_beside", "gate_distance"]

BANK_FILE = "bank.npz"
SWITCHES = ("model.match_k", "model.match_lo", "model.match_hi", "model.match_disp",
            "model.match_departure", "model.match_speed_scale")                        # inference only
MARGIN = 8                     # known frames a gap's context needs on each side (gate.CONTEXT_FRAMES)
STRIDE = 2                     # frames between the bank's candidate windows
CACHED_LENGTHS = 8             # gap lengths whose candidate contexts are kept


def match_enabled(model_cfg) -> bool:
    return int(getattr(model_cfg, "match_k", 0)) > 0


def _displacement(ref, yaw, a, b) -> np.ndarray:
    """(N, 3): the floor displacement from frame ``a - 1`` to ``b`` in the body frame at ``a - 1`` (metres, from
    centimetres) and the turn (radians, wrapped)."""
    from inbetween_jax.geometry.heading import rotate_about_up
    d = rotate_about_up(ref[b] - ref[a - 1], -yaw[a - 1]) / 100.0
    turn = (yaw[b] - yaw[a - 1] + np.pi) % (2 * np.pi) - np.pi
    return np.concatenate([d, turn[:, None]], axis=1)


@dataclasses.dataclass
class MatchBank:
    """Training motion in the CAE's space: ``clips``: per clip (D, T) float32 normalised features and its root
    track (``ref`` (T, 2), ``yaw`` (T,)).  Candidate windows are indexed per gap length (:meth:`index`)."""
    clips: list
    tracks: list
    names: list = dataclasses.field(default_factory=list)      # the source file of each clip
    _cache: dict = dataclasses.field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_transition_bank(cls, bank, skeleton, normalizer, num_joints: int, tempos=(1.0,),
                             mirror: bool = False) -> "MatchBank":
        """The CAE view of a :class:`~inbetween_jax.models.scvae.bank.TransitionBank` on the run's skeleton;
        ``tempos``: each clip also played at these speeds (resampled; 1.25 is faster, fewer frames);
        ``mirror``: each clip's left-right mirror image too (:func:`~inbetween_jax.models.cae.features.
        mirror_rows`).  Raises UserError (one line) for a bank on another skeleton or an unmirrorable rig."""
        from inbetween_jax.geometry.kinematics import forward_kinematics, local_positions
        from inbetween_jax.models.cae.features import mirror_rows, positions_to_features, smoothed_facing_yaw
        if bank.num_joints != num_joints or tuple(bank.parents) != tuple(skeleton.parents):
            raise UserError(f"motion bank: {bank.num_joints} joints on another skeleton than the run's "
                            f"{num_joints}")
        items = []
        for s, e, name in zip(bank.clip_starts[:-1], bank.clip_starts[1:], bank.names):
            lp = local_positions(bank.root_pos[s:e].astype(np.float64), bank.offsets)
            gp = forward_kinematics(bank.local_quats[s:e].astype(np.float64), lp, bank.parents)[1]
            yaw = np.unwrap(smoothed_facing_yaw(gp, skeleton))
            items.append((positions_to_features(gp, yaw), gp[:, 0, [0, 2]], yaw, str(name)))
        out = cls.from_features(items, normalizer, tempos, mirror_rows(skeleton) if mirror else None)
        if not out.clips:
            raise UserError("motion bank: no clip is long enough to match a gap in")
        return out

    @classmethod
    def from_features(cls, items, normalizer, tempos=(1.0,), mirror=None) -> "MatchBank":
        """A bank of clips already in the CAE's un-normalised features: ``items``: ``(features (T, D), floor path
        (T, 2) in cm, unwrapped facing (T,), name)`` each; every clip also played at ``tempos`` and, with ``mirror``
        (:func:`~inbetween_jax.models.cae.features.mirror_rows`' ``(perm, sign)``), mirrored.  Clips too short to
        hold a gap's context are left out (the bank may be empty)."""
        perm, sign = mirror if mirror is not None else (None, None)
        clips, tracks, names = [], [], []
        for feats, ref, yaw, name in items:
            for tempo in tempos:
                f, rf, yw = _played_at(np.asarray(feats, np.float64), np.asarray(ref, np.float64),
                                       np.asarray(yaw, np.float64), float(tempo))
                if len(f) < 2 * MARGIN + 2:
                    continue
                variants = [(f, rf, yw)]
                if mirror is not None:
                    variants.append((sign[None] * f[:, perm], rf * np.array([-1.0, 1.0]), -yw))
                for fv, rv, yv in variants:
                    clips.append(np.ascontiguousarray(normalizer(fv.astype(np.float32)).T.astype(np.float32)))
                    tracks.append((rv, yv))
                    names.append(name)
        return cls(clips, tracks, names)

    def index(self, length: int):
        """``(contexts (N, C), squared norms (N,), displacements (N, 3), where (N, 2) [clip, start])`` of every
        training window with a ``length``-frame gap and its context inside one clip; cached for the
        :data:`CACHED_LENGTHS` lengths used last."""
        if length in self._cache:
            self._cache[length] = self._cache.pop(length)              # most recently used last
        else:
            from inbetween_jax.models.cae.gate import gap_context
            while len(self._cache) >= CACHED_LENGTHS:                   # about 45 MB per length for CMU
                self._cache.pop(next(iter(self._cache)))
            ctx, disp, where = [], [], []
            for i, (x, (ref, yaw)) in enumerate(zip(self.clips, self.tracks)):
                s = np.arange(MARGIN, x.shape[1] - length - MARGIN, STRIDE)
                if len(s) == 0:
                    continue
                ctx.append(gap_context(np.broadcast_to(x, (len(s),) + x.shape), s, s + length))
                disp.append(_displacement(ref, yaw, s, s + length))
                where.append(np.stack([np.full(len(s), i), s], 1))
            if not ctx:
                self._cache[length] = None
            else:
                c = np.concatenate(ctx).astype(np.float32)
                self._cache[length] = (c, np.sum(c.astype(np.float64) ** 2, 1), np.concatenate(disp),
                                       np.concatenate(where))
        return self._cache[length]


def _played_at(feats, ref, yaw, tempo: float):
    """One clip's features (T, D), floor path (T, 2) and unwrapped facing (T,) played ``tempo`` times as fast:
    linearly resampled in time; the per-frame root velocities (the last three rows) scale with the tempo."""
    if tempo == 1.0:
        return feats, ref, yaw
    t = np.arange(0.0, len(feats) - 1 + 1e-9, tempo)
    src = np.arange(len(feats))
    f = np.stack([np.interp(t, src, col) for col in feats.T], 1)
    f[:, -3:] *= tempo
    return (f, np.stack([np.interp(t, src, ref[:, 0]), np.interp(t, src, ref[:, 1])], 1), np.interp(t, src, yaw))


def match_candidates(bank: MatchBank, x_masked, ref, yaw, a: int, b: int, k: int, disp_weight: float = 1.0,
                     exclude=None):
    """The ``k`` nearest training windows of gap ``[a, b)`` of one normalised clip image ``x_masked`` (D, T) whose
    root track is ``ref`` (T, 2) / ``yaw`` (T,) (known frames only are read), each offset-blended onto the known
    frames.  Returns ``(fills (k', D, b - a), distances (k',))``, nearest first, or ``(None, None)`` when the gap
    lacks :data:`MARGIN` known frames on a side or no training window is that long.  exclude: optional (num
    clips,) bool, clips never matched (e.g. the query's own subject, to score the bank's subjects leaving each
    out)."""
    from inbetween_jax.models.cae.gate import gap_context
    x = np.asarray(x_masked, np.float32)
    g = b - a
    if a < MARGIN or b + MARGIN > x.shape[1]:
        return None, None
    idx = bank.index(g)
    if idx is None:
        return None, None
    ctx, sq, disp, where = idx
    q = gap_context(x[None], a, b)[0].astype(np.float64)
    qd = _displacement(np.asarray(ref, np.float64), np.asarray(yaw, np.float64), np.array([a]), np.array([b]))[0]
    d = (np.maximum(sq - 2.0 * (ctx @ q.astype(np.float32)) + q @ q, 0.0) / len(q)
         + disp_weight * np.sum((disp - qd) ** 2, 1))
    if exclude is not None:
        d = np.where(np.asarray(exclude, bool)[where[:, 0]], np.inf, d)
    best = np.argsort(d)[:max(int(k), 1)]
    best = best[np.isfinite(d[best])]
    if len(best) == 0:
        return None, None
    w = (np.arange(1, g + 1) / (g + 1))[None]
    fills = []
    for i in best:
        clip, s = where[i]
        c = bank.clips[clip][:, s - 1:s + g + 1]
        d0, d1 = x[:, a - 1] - c[:, 0], x[:, b] - c[:, -1]
        fills.append(c[:, 1:-1] + (1 - w) * d0[:, None] + w * d1[:, None])
    return np.stack(fills), d[best]


def match_gap(bank: MatchBank, x_masked, ref, yaw, a: int, b: int, k: int, disp_weight: float = 1.0, exclude=None):
    """The matched fill of gap ``[a, b)``: the mean of :func:`match_candidates`' ``k`` windows.  Returns ``(fill
    (D, b - a), distance of the nearest)``, or ``(None, inf)`` where there is no candidate."""
    fills, d = match_candidates(bank, x_masked, ref, yaw, a, b, k, disp_weight, exclude)
    if fills is None:
        return None, float("inf")
    return np.mean(fills, 0).astype(np.float32), float(d[0])


def departure(fill, matched, known_pos, a: int, b: int, normalizer, num_joints: int) -> float:
    """How far a matched fill departs from the gap's fill against how far the body moves beside the gap: the mean
    joint distance (body frame) between ``matched`` and ``fill`` (normalised, (D, b - a)) over the mean joint
    travel of the known global positions ``known_pos`` (T, J, 3) from ``a - 8`` to ``a - 1`` and from ``b`` to
    ``b + 7`` (at least 1 unit).  A walk moves 20 cm or so there and its good matches depart by a fifth of that;
    a body standing still beside the gap moves ~0, and any match that moves it scores high."""
    from inbetween_jax.models.cae.features import body_positions
    dev = np.linalg.norm(body_positions(matched, normalizer, num_joints)
                         - body_positions(fill, normalizer, num_joints), axis=-1).mean()
    p = np.asarray(known_pos, np.float64)
    travel = 0.5 * (np.linalg.norm(p[a - 1] - p[a - MARGIN], axis=-1).mean()
                    + np.linalg.norm(p[b + MARGIN - 1] - p[b], axis=-1).mean())
    return float(dev / max(travel, 1.0))


def speed_beside(ref, a: int, b: int) -> float:
    """The root's mean floor speed (cm per frame) over the :data:`MARGIN` known frames on each side of gap
    ``[a, b)``: ``ref`` (T, 2) the root track in cm (known frames only are read)."""
    r = np.asarray(ref, np.float64)
    before = np.linalg.norm(np.diff(r[max(a - MARGIN, 0):a], axis=0), axis=1)
    after = np.linalg.norm(np.diff(r[b:b + MARGIN], axis=0), axis=1)
    return float(np.mean([s.mean() for s in (before, after) if len(s)] or [0.0]))


def gate_distance(distance: float, speed: float, scale: float) -> float:
    """The distance the match gate reads (``model.match_speed_scale``): ``distance / (1 + speed / scale)``, so a
    match may lie farther from the query where the body travels beside the gap (a walk's matches help, an
    everyday or dance gap's seldom do: docs/results/gate.md); ``scale`` <= 0 leaves the distance as it is."""
    return float(distance) / (1.0 + float(speed) / scale) if scale > 0 else float(distance)


def match_weight(distance: float, lo: float, hi: float) -> float:
    """The matched fill's blend weight: 1 at a distance <= ``lo``, 0 at >= ``hi`` (and for no match)."""
    if not np.isfinite(distance):
        return 0.0
    return float(np.clip((hi - distance) / max(hi - lo, 1e-12), 0.0, 1.0))
