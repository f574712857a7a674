"""Two-character data for the interaction in-betweening model: paired BVH loading, constructed pairings and
temporal splits (training batches and evaluation windows: :mod:`inbetween_jax.models.interaction.batches`).

Features and spaces are those of :mod:`inbetween_jax.models.interaction.features` (``(..., T, J, 9)``
world features, rigid ``(R, t)`` keypose spaces).

Real paired captures: ``load_pair(a, b)`` (two BVH files sharing frame timing) and
``find_pair_files(folder)`` (``<name>_A.bvh`` / ``<name>_B.bvh``, a ``pairs.txt`` list of
``a.bvh b.bvh [train|test]`` lines, or two subjects' files sharing a take id such as the CMU salsa
``60_NN_scaled.bvh`` / ``61_NN_scaled.bvh``).  :func:`load_real_pairs` resamples them to 30 Hz, converts the
detected unit to centimetres, drops joints that never move and splits whole takes (last sixth test).  Where
none exist, :func:`construct_pairs` pairs single-person clips of the same choreography (LaFAN1
``<action>_subjectN``) or consecutive clips, placing the second performer at a fixed floor offset facing the
first, time-aligned by frame index.  Such pairs are flagged ``constructed=True``.
"""
from __future__ import annotations

import dataclasses
import os
import re
from typing import Optional, Sequence

import numpy as np

from inbetween_jax.data import read_bvh
from inbetween_jax.data.features import detect_unit_scale
from inbetween_jax.data.resample import WORKING_FPS, check_tempo, resample_motion
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.geometry.heading import yaw_matrix
from inbetween_jax.models.interaction.features import (apply_space, facing_yaw, root_space,
                                                       skeleton_forward_axis, to_space, world_joint_features)

__all__ = ["PairedMotion", "PairSet", "load_pair", "find_pair_files", "static_joints", "subset_skeleton",
           "real_pair_splits", "load_real_pairs", "place_facing", "construct_pairs",
           "load_pairs", "augmented_pairs", "split_pairs", "load_pair_set"]

LAFAN_NAME = re.compile(r"^(?P<action>.+)_(?P<subject>subject\d+)\.bvh$")
TAKE_NAME = re.compile(r"^(?P<subject>[^_]+)_(?P<take>\d+)(?:_[^.]*)?\.bvh$", re.IGNORECASE)


@dataclasses.dataclass
class PairedMotion:
    """Two characters on one skeleton sharing frame timing.

    feats: (2, T, J, 9) float32 world-space features (positions in cm: constructed pairs keep the files'
    units, cm for LaFAN1 / CMU; real pairs are converted from their detected unit).
    """
    feats: np.ndarray
    skeleton: Skeleton
    forward_axis: np.ndarray
    fps: float
    name: str
    constructed: bool
    split: Optional[str] = None    # fixed split of the pair (train / test); None: temporal split

    @property
    def num_frames(self) -> int:
        return int(self.feats.shape[1])

    def slice(self, start: int, stop: int) -> "PairedMotion":
        return dataclasses.replace(self, feats=self.feats[:, start:stop])


def load_pair(path_a: str, path_b: str, name: Optional[str] = None, fps: float = WORKING_FPS,
              keep: Optional[np.ndarray] = None) -> PairedMotion:
    """Two BVH files of one interaction sharing frame timing -> :class:`PairedMotion` (real pair).

    The files must share skeleton topology and frame rate; the longer one is cut to the shorter.  Both are
    resampled to ``fps`` (:func:`~inbetween_jax.data.resample.resample_motion`), positions and offsets are
    converted to centimetres (unit scale detected from the skeleton,
    :func:`~inbetween_jax.data.features.detect_unit_scale`) and only the joints of the (J,) bool mask
    ``keep`` are kept (default: all; see :func:`static_joints`).
    """
    ma, mb = _read_pair(path_a, path_b, fps)
    return _make_pair(ma, mb, name or os.path.splitext(os.path.basename(path_a))[0], keep)


def _read_pair(path_a: str, path_b: str, fps: float):
    ma, mb = read_bvh(path_a), read_bvh(path_b)
    if not ma.skeleton.same_topology(mb.skeleton):
        raise ValueError(f"{path_a} and {path_b} use different skeletons")
    if abs(ma.frame_time - mb.frame_time) > 1e-6:
        raise ValueError(f"{path_a} ({ma.fps:.3f} fps) and {path_b} ({mb.fps:.3f} fps) differ in frame rate")
    return resample_motion(ma, fps), resample_motion(mb, fps)


def _make_pair(ma, mb, name: str, keep: Optional[np.ndarray]) -> PairedMotion:
    scale = detect_unit_scale(ma.skeleton)                  # cm per file unit (1.0 for cm files)
    n = min(ma.num_frames, mb.num_frames)
    feats = np.stack([world_joint_features(ma)[:n], world_joint_features(mb)[:n]])
    feats[..., :3] *= scale
    keep = np.ones(ma.skeleton.num_joints, bool) if keep is None else np.asarray(keep, bool)
    skel = subset_skeleton(ma.skeleton, keep, scale)
    return PairedMotion(feats[:, :, keep].astype(np.float32), skel, skeleton_forward_axis(skel), float(ma.fps),
                        name, False)


def static_joints(motions, tol_deg: float = 1e-3) -> np.ndarray:
    """(J,) bool: joints whose local rotation never moves (within ``tol_deg`` of its first frame in every
    motion) and whose descendants never move either (unused finger / eye chains).  The root is never static."""
    skel = motions[0].skeleton
    still = np.ones(skel.num_joints, bool)
    for m in motions:
        q = np.asarray(m.local_quats, np.float64)
        dot = np.abs(np.sum(q * q[:1], -1)).min(0).clip(0, 1)
        still &= np.degrees(2 * np.arccos(dot)) <= tol_deg
        still &= (np.abs(m.local_pos - m.local_pos[:1]).max(0) < 1e-9).all(-1)
    still[0] = False
    for j in range(skel.num_joints - 1, 0, -1):            # children come after parents
        if not still[j]:
            p = skel.parents[j]
            while p > 0 and still[p]:
                still[p] = False
                p = skel.parents[p]
    return still


def subset_skeleton(skel: Skeleton, keep: np.ndarray, scale: float = 1.0) -> Skeleton:
    """``skel`` restricted to the joints of the (J,) bool mask ``keep`` (closed under parents), offsets times
    ``scale``.  A kept joint whose children were all dropped gets an end site at its first child's offset."""
    idx = [int(j) for j in np.flatnonzero(keep)]
    remap = {j: i for i, j in enumerate(idx)}
    if 0 not in remap or any(skel.parents[j] not in remap for j in idx[1:]):
        raise ValueError("kept joints must include the root and every kept joint's parent")
    ends = [(remap[p], np.asarray(o, np.float64) * scale) for p, o in skel.end_sites if p in remap]
    has_child = {skel.parents[j] for j in idx[1:]} | {p for p, _ in skel.end_sites}
    for j in idx:
        if j not in has_child:
            kids = skel.children(j)
            ends.append((remap[j], np.asarray(skel.offsets[kids[0]], np.float64) * scale))
    return Skeleton(tuple(skel.names[j] for j in idx), tuple(remap.get(skel.parents[j], -1) for j in idx),
                    np.asarray(skel.offsets, np.float64)[idx] * scale, tuple(skel.channels[j] for j in idx),
                    tuple(sorted(ends, key=lambda e: e[0])))


def _take_pairs(folder: str, files) -> list:
    """Pairs of files sharing a take id (``<subject>_<take>[_suffix].bvh``, e.g. ``60_12_scaled.bvh`` with
    ``61_12_scaled.bvh``) when the folder's take-named files come from exactly two subjects."""
    found: dict = {}
    for f in sorted(files):
        m = TAKE_NAME.match(f)
        if m:
            found.setdefault(m.group("take"), {})[m.group("subject")] = f
    subjects = sorted({s for take in found.values() for s in take})
    if len(subjects) != 2:
        return []
    sa, sb = subjects
    return [(f"{sa}+{sb}_{take}", os.path.join(folder, t[sa]), os.path.join(folder, t[sb]))
            for take, t in sorted(found.items()) if len(t) == 2]


def find_pair_files(folder: str) -> list:
    """Real pairs in ``folder``: ``pairs.txt`` (``a.bvh b.bvh [train|test]`` per line, relative to the folder),
    ``<name>_A.bvh`` / ``<name>_B.bvh``, or two subjects' files sharing a take id (``60_NN*.bvh`` with
    ``61_NN*.bvh``).  Returns ``[(name, path_a, path_b)]`` (empty when none)."""
    listing = os.path.join(folder, "pairs.txt")
    if os.path.exists(listing):
        return [(n, a, b) for n, a, b, _ in _listed_pairs(folder)]
    files = set(os.listdir(folder))
    ab = [(f[:-6], os.path.join(folder, f), os.path.join(folder, f[:-6] + "_B.bvh"))
          for f in sorted(files) if f.endswith("_A.bvh") and f[:-6] + "_B.bvh" in files]
    return ab or _take_pairs(folder, files)


def _listed_pairs(folder: str) -> list:
    out = []
    with open(os.path.join(folder, "pairs.txt")) as f:
        for line in f:
            parts = line.split("#", 1)[0].split()
            if len(parts) in (2, 3):
                a, b = (os.path.join(folder, p) for p in parts[:2])
                out.append((os.path.splitext(parts[0])[0], a, b, parts[2] if len(parts) == 3 else None))
    return out


def real_pair_splits(folder: str, names: Sequence[str]) -> list:
    """Fixed train / test split of a folder's real pairs (whole takes): the ``pairs.txt`` third column where
    given, else the last ``ceil(n / 6)`` pairs in name order are test (CMU salsa: takes 01-11 train, 12-13
    test); a single pair is split in time instead (None)."""
    listed = {}
    if os.path.exists(os.path.join(folder, "pairs.txt")):
        listed = {n: s for n, _, _, s in _listed_pairs(folder) if s}
    if listed:
        return [listed.get(n, "train") for n in names]
    if len(names) < 2:
        return [None] * len(names)
    n_test = -(-len(names) // 6)
    order = sorted(range(len(names)), key=lambda i: names[i])
    test = set(order[-n_test:])
    return ["test" if i in test else "train" for i in range(len(names))]


def load_real_pairs(folder: str, fps: float = WORKING_FPS) -> list:
    """Every real pair of ``folder`` (:func:`find_pair_files`) at ``fps``, in centimetres, without the joints
    that never move in any of them (:func:`static_joints`), with the fixed split of :func:`real_pair_splits`."""
    found = find_pair_files(folder)
    motions = [_read_pair(a, b, fps) for _, a, b in found]
    for (_, a, _), (m, _) in zip(found, motions):
        if not m.skeleton.same_topology(motions[0][0].skeleton):
            raise ValueError(f"{a}: its skeleton differs from {found[0][1]}'s; use one skeleton per folder")
    keep = ~static_joints([m for pair in motions for m in pair])
    splits = real_pair_splits(folder, [n for n, _, _ in found])
    return [dataclasses.replace(_make_pair(ma, mb, name, keep), split=s)
            for (name, _, _), (ma, mb), s in zip(found, motions, splits)]


def _placement_space(root_feat: np.ndarray, forward_axis):
    """Root space of one root feature vector (9,) with the rotation computed in float32 (JAX): the
    constructed pairs (and so every recorded training run) were made with this rotation; a float64 one
    moves the pairs by up to one float32 ulp, which the GAN training amplifies."""
    import jax.numpy as jnp
    _, t = root_space(root_feat, forward_axis)
    return yaw_matrix(jnp.asarray(facing_yaw(root_feat, forward_axis))), t


def place_facing(feat_a: np.ndarray, feat_b: np.ndarray, forward_axis, distance: float) -> np.ndarray:
    """Move clip B rigidly so that at frame 0 its root is ``distance`` in front of A's root (floor plane)
    and faces A.  feat_a, feat_b: (T, J, 9) -> B's new features (T, J, 9)."""
    Ra, ta = _placement_space(feat_a[0, 0], forward_axis)
    Rb, tb = _placement_space(feat_b[0, 0], forward_axis)
    target_t = ta + Ra @ np.array([0.0, 0.0, distance])
    target_R = Ra @ yaw_matrix(np.asarray(np.pi))
    local = to_space(feat_b, Rb, tb)
    return apply_space(local, target_R, target_t)


def _group_pairs(paths: Sequence[str]) -> list:
    """Consecutive pairs of clips with the same choreography (LaFAN1 ``<action>_subjectN``), else of
    consecutive files: ``[(name, path_a, path_b)]``."""
    groups: dict = {}
    for p in sorted(paths):
        m = LAFAN_NAME.match(os.path.basename(p))
        groups.setdefault(m.group("action") if m else None, []).append(p)
    out = []
    for action, items in sorted(groups.items(), key=lambda kv: str(kv[0])):
        for a, b in zip(items[:-1], items[1:]):
            sa = os.path.splitext(os.path.basename(a))[0]
            sb = os.path.splitext(os.path.basename(b))[0]
            out.append((f"{sa}+{sb}", a, b))
    return out


def construct_pairs(paths: Sequence[str], distance: float = 150.0) -> list:
    """Constructed pairs from single-person BVH clips (see module docstring): list of PairedMotion."""
    out = []
    for name, pa, pb in _group_pairs(paths):
        ma, mb = read_bvh(pa), read_bvh(pb)
        if not ma.skeleton.same_topology(mb.skeleton) or abs(ma.frame_time - mb.frame_time) > 1e-6:
            continue
        n = min(ma.num_frames, mb.num_frames)
        fa = skeleton_forward_axis(ma.skeleton)
        a, b = world_joint_features(ma)[:n], world_joint_features(mb)[:n]
        b = place_facing(a, b, fa, distance)
        out.append(PairedMotion(np.stack([a, b]).astype(np.float32), ma.skeleton, fa, float(ma.fps), name, True))
    return out


def load_pairs(source: Optional[str] = None, distance: float = 150.0) -> list:
    """All pairs of a source: a folder with real pairs (``find_pair_files``), else constructed pairs of its
    clips; ``None`` / ``"embedded"`` -> ``$LAFAN1_DIR`` or the shipped CMU clips (constructed)."""
    from inbetween_jax.data.datasets import EMBEDDED_DIR, resolve_source
    source = resolve_source(source)
    folder = EMBEDDED_DIR if source == "embedded" else source
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"data folder {folder!r} does not exist")
    if find_pair_files(folder):
        return load_real_pairs(folder)
    if source == "embedded":   # the shipped clips are short: pair within its file-level train / test split
        from inbetween_jax.data.datasets import split_files
        pairs = []
        for split in ("train", "test"):
            pairs += [dataclasses.replace(p, split=split)
                      for p in construct_pairs(split_files("embedded", split), distance)]
        return pairs
    paths = [os.path.join(folder, f) for f in os.listdir(folder) if f.lower().endswith(".bvh")]
    pairs = construct_pairs(paths, distance)
    if not pairs:
        raise FileNotFoundError(f"no pairable BVH clips in {folder!r}")
    return pairs


def augmented_pairs(pairs: Sequence[PairedMotion], source: Optional[str], tempo=(), reverse: bool = False) -> list:
    """``pairs`` plus augmented copies for training: for each speed ``s`` of ``tempo`` the same real takes
    resampled from the files to ``fps / s`` and played at ``fps`` (``s`` > 1 faster; named ``<take>@<s>x``),
    then, with ``reverse``, every pair so far played backwards (``<name>@rev``).  Window sampling weighs pairs
    by length, so the copies take their share of every batch.

    Raises:
        ValueError: ``tempo`` for a source without real pairs, or a non-positive speed (one line).
    """
    out = list(pairs)
    if tempo:
        if any(p.constructed or p.split is None for p in pairs):
            raise ValueError(f"{source}: data.tempo needs whole real takes (constructed or time-split pairs here)")
        check_tempo(tempo)
        from inbetween_jax.data.datasets import resolve_source
        folder, names, fps = resolve_source(source), {p.name for p in pairs}, pairs[0].fps
        for s in tempo:
            copies = [p for p in load_real_pairs(folder, fps / s) if p.name in names]
            if any(p.feats.shape[2] != pairs[0].feats.shape[2] for p in copies):
                raise ValueError(f"{folder}: at speed {s:g} other joints are static; drop that speed")
            out += [dataclasses.replace(p, fps=fps, name=f"{p.name}@{s:g}x") for p in copies]
    if reverse:
        out += [dataclasses.replace(p, feats=np.ascontiguousarray(p.feats[:, ::-1]), name=f"{p.name}@rev")
                for p in out]
    return out


def split_pairs(pairs: Sequence[PairedMotion], split: str, fractions=(0.85, 0.05, 0.10)) -> list:
    """Temporal split of every pair (the paper's 90/5/5 style split, here 85/5/10 by default so that
    long-horizon test windows fit): ``split`` in train / val / test, or ``fit`` (train without val).

    Pairs with a fixed ``split`` (whole takes) are kept whole in theirs; their validation split is the last
    training pair in name order (when there are at least two), held out of ``fit`` together with the
    constructed pairs that share a clip with it -- checkpoint selection never sees the test takes.  A
    temporally split pair's ``fit`` part is its ``train`` part (its ``val`` part lies between train and test)."""
    if split not in ("train", "val", "test", "fit"):
        raise ValueError(f"unknown pair split {split!r}; choose train, val, test or fit")
    fixed_train = sorted(p.name for p in pairs if p.split == "train")
    held = set(fixed_train[-1:]) if len(fixed_train) >= 2 else set()
    clips = {c for p in pairs if p.name in held and p.constructed for c in p.name.split("+")}
    shares_clip = lambda p: p.constructed and bool(clips & set(p.name.split("+")))  # noqa: E731
    idx = {"train": 0, "fit": 0, "val": 1, "test": 2}[split]
    edges = np.cumsum((0.0,) + tuple(fractions))
    out = []
    for p in pairs:
        if p.split is not None:
            if split == "val":
                keep = p.name in held
            elif split == "fit":
                keep = p.split == "train" and p.name not in held and not shares_clip(p)
            else:
                keep = p.split == split
            if keep:
                out.append(p)
            continue
        a, b = int(round(edges[idx] * p.num_frames)), int(round(edges[idx + 1] * p.num_frames))
        if b - a > 1:
            out.append(p.slice(a, b))
    return out


@dataclasses.dataclass
class PairSet:
    """The pairs of one split of a source (:func:`load_pair_set`) and where they came from.

    pairs: the split's :class:`PairedMotion` (one skeleton); all_pairs: ``[{name, frames, constructed}]`` of
    every pair of the source before splitting.
    """
    pairs: list
    split: str
    all_pairs: list

    @property
    def skeleton(self) -> Skeleton:
        return self.pairs[0].skeleton

    @property
    def forward_axis(self) -> np.ndarray:
        return self.pairs[0].forward_axis

    @property
    def num_joints(self) -> int:
        return int(self.pairs[0].feats.shape[2])

    @property
    def constructed(self) -> bool:
        return any(p["constructed"] for p in self.all_pairs)

    @property
    def num_frames(self) -> int:
        return int(sum(p.num_frames for p in self.pairs))


def load_pair_set(source: Optional[str], split: str, distance: float = 150.0,
                  fractions=(0.85, 0.05, 0.10)) -> PairSet:
    """:func:`load_pairs` of ``source`` cut to ``split`` (:func:`split_pairs`).

    Raises:
        ValueError: the split holds no pair (one line naming the source).
    """
    pairs = load_pairs(source, distance)
    part = split_pairs(pairs, split, fractions)
    if not part:
        raise ValueError(f"{source}: no pair has frames in the {split!r} split")
    return PairSet(part, split, [dict(name=p.name, frames=p.num_frames, constructed=p.constructed) for p in pairs])
