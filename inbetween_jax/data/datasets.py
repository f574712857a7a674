"""One entry point for every data source: LaFAN1 folders, the embedded CMU default, any BVH folder.

``source`` is resolved as: an explicit argument, else ``$LAFAN1_DIR`` if set, else ``"embedded"``.

* ``"embedded"`` -- the real CMU mocap shipped in ``inbetween_jax/assets/cmu30`` (30 Hz, 21 joints);
  subjects 13 and 14 are the test split, the rest train.
* a folder of LaFAN1 files (``<action>_subjectN.bvh``) -- the official LaFAN1 splits and windows.
* ``"cmu"`` -- the embedded test files; for training the embedded ones plus the larger CMU sets of the shared
  mocap folder (``$INBETWEEN_SHARED_DATA``, else ``../shared/data``), all on the embedded skeleton and unit
  (:mod:`inbetween_jax.data.sources`).
* any other folder of BVH files on one skeleton -- ``<stem>`` sorted, the last 20 % test; loading its
  training split prints one line on stderr naming the train / test counts and the test files.

Splits: ``train``, ``test``, ``benchmark`` (test files, 65-frame windows at offset 40), and for checkpoint
selection ``val`` (about 10 % of the training files, chosen by a hash of the file name) and ``fit`` (``train``
minus ``val``); see :func:`~inbetween_jax.data.sources.val_files`.

Frame rate: window lengths, offsets and per-frame thresholds count frames at :data:`WORKING_FPS` (30, the
LaFAN1 and embedded rate; the ``fps`` argument changes it). Files at any other rate (120 Hz CMU, 50, 24 ...)
are resampled to it as they are read -- rotations slerped, positions interpolated, at times ``k / fps`` -- and
one line on stderr says so (``data: <folder>: 120 fps files resampled to 30 fps``).

Units: positions stay in the files' units. The centimetres per unit are detected from the skeleton's leg length
(:func:`~inbetween_jax.data.features.detect_unit_scale`: exactly 1.0 for LaFAN1 and the embedded data, about 130
for the 1/128-scaled CMU salsa files) or given as ``unit_scale``; the centimetre contact thresholds are applied
through it and :class:`MotionWindows` carries it as ``unit_scale``. Files of one folder must share a skeleton
and a unit (one-line ValueError naming the first file that differs otherwise).

Windows are prepared once into an ``.npz`` cache keyed by the files' names, sizes and mtimes and the
window settings (frame rate and any explicit unit scale included), under ``$INBETWEEN_JAX_CACHE`` (default
``~/.cache/inbetween_jax``).
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from collections import Counter
from typing import Optional

import numpy as np

from inbetween_jax.data import lafan1, sources
from inbetween_jax.data.bvh import Motion, read_bvh
from inbetween_jax.data.features import detect_unit_scale
from inbetween_jax.data.files import (EMBEDDED_DIR, EMBEDDED_TEST_PREFIXES,  # noqa: F401 (re-exported)
                                      bvh_files, embedded_files, progress)
from inbetween_jax.data.resample import WORKING_FPS, nominal_fps, resample_motion
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.data.windows import MotionWindows, windows_from_motions

CACHE_VERSION = 2
SPLITS = ("train", "test", "benchmark", "val", "fit", "val-subjects", "fit-subjects", "fit-activities",
          "val-activities")
HELD_OUT_SPLITS = {"val": "file", "fit": "file", "val-subjects": "subject", "fit-subjects": "subject",
                   "fit-activities": "subject"}
# ``cmu`` only: ``fit-activities`` is ``fit-subjects`` without these subjects, whose activities no other training
# subject performs much (sports: basketball, swordplay; Indian dance; karate), ``val-activities`` their files:
# how a model trained without an activity does on it (checkpoints are still chosen on ``val-subjects``)
LEFT_OUT_ACTIVITY_SUBJECTS = {"06": "sports", "94": "dance", "135": "martial arts"}
GENERIC_CONTACT_VELFACTOR = 1.0  # squared cm per frame


def resolve_source(source: Optional[str] = None) -> str:
    """The data source to use: ``source``, else ``$LAFAN1_DIR``, else ``"embedded"``."""
    if source:
        return source
    return os.environ.get("LAFAN1_DIR") or "embedded"


def is_lafan1(source: str) -> bool:
    return source not in sources.NAMED_SOURCES and os.path.isdir(source) and any(
        lafan1._NAME.match(f) for f in os.listdir(source))


def split_files(source: str, split: str) -> list:
    """BVH paths of ``split`` (``train`` / ``test`` / ``benchmark`` / ``val`` / ``fit`` / ``val-subjects`` /
    ``fit-subjects``) for ``source``.

    A generic folder's files are sorted by name and the last 20 % (at least one) are the test split; a
    folder holding a single file uses it for both.  ``val`` is about 10 % of the ``train`` files (by a hash of
    their names, :func:`~inbetween_jax.data.sources.val_files`), ``fit`` the rest of ``train``.
    ``val-subjects`` / ``fit-subjects`` cut the same way by whole performers (CMU subject, LaFAN1 subject), so
    no validation subject is trained on, as the ``cmu`` test subjects are not.  ``fit-activities`` /
    ``val-activities`` (``cmu`` only) leave the subjects of :data:`LEFT_OUT_ACTIVITY_SUBJECTS` out of
    ``fit-subjects`` too / are their files.
    """
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; choose {', '.join(SPLITS)}")
    if split in ("fit-activities", "val-activities"):
        if source != sources.CMU:
            raise ValueError(f"split {split!r} is defined for the cmu source only")
        left = [f for f in split_files(source, "train") if sources.subject_of(f) in LEFT_OUT_ACTIVITY_SUBJECTS]
        return left if split == "val-activities" else [f for f in split_files(source, "fit-subjects")
                                                        if f not in left]
    if split in HELD_OUT_SPLITS:
        train = split_files(source, "train")
        val = sources.val_files(train, by=HELD_OUT_SPLITS[split])
        return val if split.startswith("val") else [f for f in train if f not in val]
    if source == sources.CMU:
        return sources.cmu_split_files(split)
    if source == "embedded":
        return embedded_files(split)
    if not is_lafan1(source):
        files = bvh_files(source)
        if len(files) == 1:
            return files
        test = files[min(int(round(len(files) * 0.8)), len(files) - 1):]
        return test if split != "train" else [f for f in files if f not in test]
    return lafan1.lafan1_files(source, lafan1.split_spec(split)["subjects"])


def split_note(source: str) -> Optional[str]:
    """The line telling which files of a generic BVH folder are train and test (None for LaFAN1 / embedded)."""
    source = resolve_source(source)
    if source in sources.NAMED_SOURCES or is_lafan1(source):
        return None
    train, test = split_files(source, "train"), split_files(source, "test")
    if train == test:
        return f"data: {source}: 1 file ({os.path.basename(test[0])}), used for both training and test"
    names = [os.path.basename(f) for f in test]
    if len(names) > 6:
        names = names[:4] + ["...", names[-1]]
    return (f"data: {source}: {len(train)} train / {len(test)} test files (the last 20 % by name); "
            f"test: {', '.join(names)}")


def val_note(source: str, split: str) -> Optional[str]:
    """The line naming the validation files when ``split`` holds files out (:data:`HELD_OUT_SPLITS`; None
    otherwise)."""
    if split not in HELD_OUT_SPLITS:
        return None
    train, val = split_files(source, "train"), split_files(source, val_split_of(split))
    names = [os.path.basename(f) for f in val]
    if len(names) > 6:
        names = names[:5] + ["..."]
    how = "by a hash of the name" if HELD_OUT_SPLITS[split] == "file" else "whole subjects, by a hash of the subject"
    return (f"data: {resolve_source(source)}: validation split {len(val)} of {len(train)} training files "
            f"({how}), fit on the other {len(train) - len(val)}: {', '.join(names)}")


def val_split_of(split: str) -> str:
    """The validation split that goes with a training split: ``val-subjects`` for ``fit-subjects`` /
    ``val-subjects``, else ``val``."""
    return "val-subjects" if HELD_OUT_SPLITS.get(split) == "subject" else "val"


def is_fit_split(split: str) -> bool:
    """Whether a run trained on ``split`` holds validation files out (and so selects its checkpoint on them)."""
    return split in ("fit", "fit-subjects", "fit-activities")


def _part_of_train(split: str) -> bool:
    """Whether ``split``'s files are (some of) the training files: ``train`` itself, a split holding files out
    (:data:`HELD_OUT_SPLITS`) or ``val-activities``."""
    return split in ("train", "val-activities") or split in HELD_OUT_SPLITS


def window_settings(source: str, split: str, fps: float = WORKING_FPS) -> dict:
    """Window length, offset, past frames, root forward axis, contact threshold and frame rate of a split."""
    spec = lafan1.split_spec("train" if _part_of_train(split) else split)
    if is_lafan1(source):
        forward, velfactor = lafan1.ROOT_FORWARD_AXIS, lafan1.CONTACT_VELFACTOR
    else:
        # forward inferred from the skeleton; the official 0.02 cm^2/frame^2 contact threshold labels
        # almost no CMU stance frames (their ankles pivot ~0.5-1 cm per frame at 30 Hz), so use 1 cm/frame
        forward, velfactor = None, GENERIC_CONTACT_VELFACTOR
    return dict(window=spec["window"], offset=spec["offset"], n_past=lafan1.N_PAST, forward_axis=forward,
                contact_velfactor=velfactor, fps=float(fps))


def load_motions(source: Optional[str] = None, split: str = "train", fps: float = WORKING_FPS,
                 unit_scale: Optional[float] = None) -> list:
    """Whole motions (list of :class:`Motion`) of a split, all on one skeleton, at ``fps`` frames per second.

    Files at another rate are resampled (:func:`~inbetween_jax.data.resample.resample_motion`) and a line on
    stderr says so; loading a generic folder's training split also names its test files there.  Positions stay
    in the files' units: ``detect_unit_scale(motions[0].skeleton)`` gives centimetres per unit.  Files whose
    bone lengths put them in different units raise ValueError unless ``unit_scale`` (cm per unit, asserted for
    every file) is given.
    """
    source = resolve_source(source)
    _notice(split_note(source) if split == "train" else val_note(source, split))
    motions, note = _read_motions(source, split, fps, unit_scale)
    _notice(note)
    return motions


def load_dataset(source: Optional[str] = None, split: str = "train", window: Optional[int] = None,
                 offset: Optional[int] = None, use_cache: bool = True, fps: float = WORKING_FPS,
                 unit_scale: Optional[float] = None) -> MotionWindows:
    """Canonicalised windows of a split (see module docstring), cached as npz.

    ``window`` / ``offset`` override the split's defaults (50/20 train and test, 65/40 benchmark), counted in
    frames at ``fps`` (files at other rates are resampled).  Foot contacts use centimetre thresholds through
    ``unit_scale`` (cm per file unit; detected from the skeleton when None, see
    :func:`~inbetween_jax.data.features.detect_unit_scale`), which the result carries as ``.unit_scale``.
    """
    source = resolve_source(source)
    files = split_files(source, split)
    ws = window_settings(source, split, fps)
    if window is not None:
        ws["window"] = int(window)
    if offset is not None:
        ws["offset"] = int(offset)
    if unit_scale is not None:
        ws["unit_scale"] = _check_scale(unit_scale)
    _notice(split_note(source) if split == "train" else val_note(source, split))
    key = _cache_key(files, {**ws, "cmu": sources.CMU_VERSION} if source == sources.CMU else ws)
    path = os.path.join(cache_dir(), "windows", f"{split}-{key}.npz")
    if use_cache and os.path.exists(path):
        try:
            data, note = _load_npz(path)
            _notice(note)
            return data
        except (OSError, ValueError, KeyError):
            pass  # a damaged cache is rebuilt below
    motions, note = _read_motions(source, split, fps, unit_scale)
    _notice(note)
    scale = ws.get("unit_scale") or detect_unit_scale(motions[0].skeleton)
    forward = ws["forward_axis"] or tuple(motions[0].skeleton.forward_axis())
    data = windows_from_motions(motions, ws["window"], ws["offset"], ws["n_past"], forward,
                                ws["contact_velfactor"], scale)
    if use_cache:
        _save_npz(path, data, note)
    return data


def _read_motions(source: str, split: str, fps: float, unit_scale: Optional[float]):
    """(motions at ``fps``, the resampling notice or None); one skeleton and one unit per folder."""
    files = split_files(source, split)
    if source == sources.CMU and _part_of_train(split):
        return sources.read_cmu_train(files, split, fps)
    motions, rates = [], Counter()
    scale0 = None
    for f in progress(files, f"reading {split} BVH"):
        m = read_bvh(f)
        if motions:  # checked as read: a wrong file fails before the rest of the folder is parsed
            first = motions[0]
            if not m.skeleton.same_topology(first.skeleton):
                raise ValueError(f"{m.source}: its skeleton differs from {first.source} "
                                 f"({skeleton_difference(m.skeleton, first.skeleton)}); use one skeleton per folder")
            if scale0 is not None:
                s = detect_unit_scale(m.skeleton)
                if max(s, scale0) / min(s, scale0) > 1.5:
                    raise ValueError(f"{m.source}: its bone lengths put it at {s:g} cm per unit but {first.source} "
                                     f"at {scale0:g} (files in different units?); use one unit per folder")
        elif unit_scale is None:
            scale0 = detect_unit_scale(m.skeleton)
        src = nominal_fps(m.frame_time)
        r = resample_motion(m, fps)
        if r is not m:
            rates[src] += 1
        motions.append(r)
    note = None
    if rates:
        folder = source
        if len(rates) == 1 and sum(rates.values()) == len(files):
            what = f"{_fmt_fps(next(iter(rates)))} fps files"
        else:
            what = ", ".join(f"{n} file{'s' if n > 1 else ''} at {_fmt_fps(r)} fps" for r, n in sorted(rates.items()))
        note = f"data: {folder}: {what} resampled to {_fmt_fps(fps)} fps"
    return motions, note


def skeleton_difference(a: Skeleton, b: Skeleton) -> str:
    """How skeleton ``a`` differs from ``b`` in joints or hierarchy, in a few words ("" when the same)."""
    if a.num_joints != b.num_joints:
        return f"{a.num_joints} joints instead of {b.num_joints}"
    for j, (x, y) in enumerate(zip(a.names, b.names)):
        if x != y:
            return f"joint {j} is {x!r} instead of {y!r}"
    for j, (x, y) in enumerate(zip(a.parents, b.parents)):
        if x != y:
            return f"joint {a.names[j]!r} hangs from {a.names[x]!r} instead of {b.names[y]!r}"
    return ""


def _check_scale(unit_scale) -> float:
    scale = float(unit_scale)
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"unit_scale must be a positive number of cm per file unit, got {unit_scale!r}")
    return scale


def _fmt_fps(fps: float) -> str:
    return f"{fps:g}" if abs(fps - round(fps)) < 1e-9 else f"{fps:.3f}".rstrip("0")


def _notice(line: Optional[str]) -> None:
    if line:
        print(line, file=sys.stderr, flush=True)


def cache_dir() -> str:
    from inbetween_jax.paths import cache_root
    return cache_root()


def _cache_key(files, settings) -> str:
    h = hashlib.sha1(json.dumps([CACHE_VERSION, settings], sort_keys=True, default=list).encode())
    for f in files:
        st = os.stat(f)
        h.update(f"{os.path.abspath(f)}|{st.st_size}|{st.st_mtime_ns}".encode())
    return h.hexdigest()[:16]


def _save_npz(path: str, data: MotionWindows, note: Optional[str] = None) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + f".tmp{os.getpid()}.npz"
    np.savez(tmp, local_quats=data.local_quats, root_pos=data.root_pos, contacts=data.contacts,
             seq_names=np.asarray(data.seq_names), fps=np.float64(data.fps),
             unit_scale=np.float64(data.unit_scale), note=np.asarray(note or ""),
             skeleton=np.asarray(json.dumps(data.skeleton.to_dict())))
    os.replace(tmp, path)


def _load_npz(path: str):
    """(MotionWindows, the resampling notice stored with them or None)."""
    with np.load(path, allow_pickle=False) as z:
        skel = Skeleton.from_dict(json.loads(str(z["skeleton"])))
        data = MotionWindows(z["local_quats"], z["root_pos"], z["contacts"], skel,
                             [str(s) for s in z["seq_names"]], float(z["fps"]), float(z["unit_scale"]))
        return data, (str(z["note"]) or None)


__all__ = ["Motion", "MotionWindows", "SPLITS", "HELD_OUT_SPLITS", "val_split_of", "is_fit_split", "WORKING_FPS", "detect_unit_scale", "load_dataset", "load_motions",
           "resolve_source", "skeleton_difference", "split_files", "split_note", "val_note", "window_settings"]
