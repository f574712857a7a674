"""The ``cmu`` source (more real CMU mocap for training, the embedded test files for testing) and the
validation split of every source.

``cmu``:

* test / benchmark -- exactly the embedded default's test files (``assets/cmu30``, subjects 13 and 14), so
  ``cmu`` and ``embedded`` are scored on the same windows;
* train -- the embedded training files plus, from the shared mocap folder
  (:func:`~inbetween_jax.paths.shared_data_dir`), ``cmu_bvh/*.bvh``, ``cmu_more/daz43/*.bvh``,
  ``cmu_more/mb31/*.bvh`` (another rig: put on the 43-joint body of ``cmu_bvh/02_01.bvh`` by bone directions,
  :func:`~inbetween_jax.data.rig_transfer.transfer_rig`) and both dancers of every ``cmu_pairs`` take, each as
  a single-person motion.  Trials of CMU subjects 13 and 14 are never
  trained on, trials already in the embedded set (compared by trial name ``NN_MM``) are dropped, the 31-joint
  ``cmu_bvh`` files (16_01, 16_02, 18_01, with CMU's ASF joint names) take the mb31 route, and files on any
  other skeleton are skipped.
  Every training motion is restricted to the embedded joints (same order; the 43-joint files' extra joints are
  fingers and eyes, leaves), converted to the embedded unit (the ``cmu_pairs`` files are in 1/128 units; the
  factor comes from :func:`~inbetween_jax.data.features.detect_unit_scale`, made exact by the leg-length ratio
  when the file is the same generic body), loses a leading T-pose frame and is resampled to the working rate.

Validation (``val``, for checkpoint selection) is cut from a source's training files: about
:data:`VAL_FRACTION` of them (at least one), chosen by a SHA-1 hash of the file name, so the choice is
deterministic and does not depend on the folder's order.  Both dancers of a ``cmu_pairs`` take go to the same
side.  ``fit`` is the training files minus ``val``; ``train`` keeps meaning all training files.
``val-subjects`` / ``fit-subjects`` cut by whole performers instead (``val_files(..., by="subject")``: the CMU
subject of a trial name, the salsa pair as one, LaFAN1's ``subjectN``), so validation, like the ``cmu`` test
split, is motion of people never trained on (``train.split=fit-subjects``).
"""
from __future__ import annotations

import functools
import hashlib
import os
import re
from collections import Counter, OrderedDict

import numpy as np

from inbetween_jax.data.files import EMBEDDED_DIR, embedded_files, progress

CMU = "cmu"
NAMED_SOURCES = ("embedded", CMU)
CMU_VERSION = 3             # part of the window-cache key: bump when the conversion below changes
MB31_FOLDER = os.path.join("cmu_more", "mb31")     # the 31-joint rig, put on the body by bone directions
CMU_FOLDERS = ("cmu_bvh", os.path.join("cmu_more", "daz43"), MB31_FOLDER, "cmu_pairs")
HELD_OUT_SUBJECTS = ("13", "14")
VAL_FRACTION = 0.1
TPOSE_TOL = 0.01            # max |1 - |w|| of the non-root joints' rotations at frame 0 for a T-pose frame
_TRIAL = re.compile(r"^(\d+)_(\d+)")
_PAIR = re.compile(r"^(60|61)_(\d+)_scaled$", re.IGNORECASE)
_LAFAN1_SUBJECT = re.compile(r"_(subject\d+)$", re.IGNORECASE)
VAL_GROUPINGS = ("file", "subject")
_JOINT = re.compile(r"^\s*(?:ROOT|JOINT)\s+(\S+)")

__all__ = ["CMU", "NAMED_SOURCES", "VAL_FRACTION", "VAL_GROUPINGS", "trial_name", "cmu_split_files", "cmu_train_plan",
           "cmu_unavailable", "val_files", "reference_skeleton", "to_reference", "read_cmu_train"]


def trial_name(path: str):
    """The CMU trial name ``NN_MM`` of a file (``"07_05"`` for ``07_05.bvh``), or None."""
    m = _TRIAL.match(os.path.basename(path))
    return f"{int(m.group(1)):02d}_{int(m.group(2)):02d}" if m else None


def _held_out(path: str) -> bool:
    name = trial_name(path)
    return name is not None and name.split("_")[0] in HELD_OUT_SUBJECTS


@functools.lru_cache(maxsize=None)
def _header_joints(path: str, mtime_ns: int) -> tuple:
    names = []
    with open(path, "r", errors="replace") as fh:
        for line in fh:
            if line.strip().upper().startswith("MOTION"):
                break
            m = _JOINT.match(line)
            if m:
                names.append(m.group(1))
    return tuple(names)


def _on_reference(path: str, ref_names) -> bool:
    """Whether the file's hierarchy (read up to ``MOTION`` only) holds every embedded joint, root first."""
    names = _header_joints(path, os.stat(path).st_mtime_ns)
    return bool(names) and names[0] == ref_names[0] and set(ref_names) <= set(names)


def _on_mb31_rig(path: str) -> bool:
    """Whether the file's hierarchy is CMU's 31-joint rig (the MotionBuilder or the ASF names), which
    :func:`~inbetween_jax.data.rig_transfer.transfer_rig` puts on the training body."""
    from inbetween_jax.data.rig_transfer import on_31_joint_rig
    return on_31_joint_rig(_header_joints(path, os.stat(path).st_mtime_ns))


@functools.lru_cache(maxsize=1)
def _body_template():
    """Two frames of ``cmu_bvh/02_01.bvh``: the 43-joint body the mb31 captures are put on."""
    from inbetween_jax.data.bvh import read_bvh
    from inbetween_jax.paths import shared_data_dir
    return read_bvh(os.path.join(shared_data_dir(required=True), "cmu_bvh", "02_01.bvh"), 0, 2)


def cmu_train_plan() -> tuple:
    """``(files, dropped)``: the ``cmu`` training files (embedded train first, then each shared folder,
    sorted) and ``dropped`` = {"subjects 13/14": [...], "duplicates": [...], "other skeleton": [...]}.

    Raises UserError (one line) when the shared folder is missing."""
    from inbetween_jax.paths import shared_data_dir
    shared = shared_data_dir(required=True)
    files = embedded_files("train")
    seen = {trial_name(f) for f in embedded_files("train") + embedded_files("test")}
    ref_names = reference_skeleton().names
    dropped = {"subjects 13/14": [], "duplicates": [], "other skeleton": []}
    for sub in CMU_FOLDERS:
        folder = os.path.join(shared, sub)
        if not os.path.isdir(folder):
            from inbetween_jax.errors import UserError
            raise UserError(f"{folder}: missing; the cmu source reads {', '.join(CMU_FOLDERS)} there")
        for f in sorted(os.path.join(folder, n) for n in os.listdir(folder) if n.lower().endswith(".bvh")):
            name = trial_name(f)
            if _held_out(f):
                dropped["subjects 13/14"].append(f)
            elif name in seen:
                dropped["duplicates"].append(f)
            elif not (_on_reference(f, ref_names) or _on_mb31_rig(f)):
                dropped["other skeleton"].append(f)
            else:
                files.append(f)
                seen.add(name)
    return files, dropped


def cmu_unavailable():
    """None when the ``cmu`` source's folders are there, else one line saying why not (the shared mocap folder,
    or one of :data:`CMU_FOLDERS` in it, missing)."""
    from inbetween_jax.errors import UserError
    from inbetween_jax.paths import shared_data_dir
    try:
        shared = shared_data_dir(required=True)
    except UserError as e:
        return str(e)
    missing = [sub for sub in CMU_FOLDERS if not os.path.isdir(os.path.join(shared, sub))]
    return f"{shared} lacks {', '.join(missing)}" if missing else None


def cmu_split_files(split: str) -> list:
    """BVH paths of ``split`` (train / test / benchmark) of the ``cmu`` source (see the module docstring)."""
    if split == "train":
        return cmu_train_plan()[0]
    return embedded_files(split)


def _stem(path: str) -> str:
    return os.path.splitext(os.path.basename(path))[0]


def subject_of(path: str) -> str | None:
    """The CMU subject of a trial file ``NN_MM...`` (``"135"``, ``"06"``), None for other names (a salsa take's
    is its dancer's, 60 or 61)."""
    t = _TRIAL.match(_stem(path))
    return t.group(1) if t else None


def _val_group(path: str, by: str = "file") -> str:
    """What the validation hash is taken of.  ``by="file"``: the file name, or ``salsa_NN`` for both dancers of
    a take.  ``by="subject"``: the performer -- the CMU subject of a trial name ``NN_MM`` (``salsa`` for every
    take of the salsa pair, subjects 60 and 61 dance together), LaFAN1's ``subjectN`` suffix, else the file."""
    stem = _stem(path)
    m = _PAIR.match(stem)
    if by == "subject":
        if m:
            return "salsa"
        t, lf = _TRIAL.match(stem), _LAFAN1_SUBJECT.search(stem)
        return f"subject {int(t.group(1)):02d}" if t else lf.group(1).lower() if lf else stem.lower()
    return f"salsa_{int(m.group(2)):02d}" if m else stem.lower()


def val_files(train: list, fraction: float = VAL_FRACTION, by: str = "file") -> list:
    """The validation files among ``train`` (in ``train``'s order): whole groups (:func:`_val_group`; ``by``
    "file": trials, "subject": performers) taken in the order of the SHA-1 of their name until at least
    ``round(fraction * len(train))`` files (>= 1)."""
    if by not in VAL_GROUPINGS:
        raise ValueError(f"unknown validation grouping {by!r}; choose {', '.join(VAL_GROUPINGS)}")
    groups = OrderedDict()
    for f in train:
        groups.setdefault(_val_group(f, by), []).append(f)
    if len(groups) < 2:
        what = "trials" if by == "file" else "subjects"
        raise ValueError(f"a validation split needs training files of at least two {what}, got "
                         f"{len(train)} file{'s' if len(train) != 1 else ''} ({', '.join(map(os.path.basename, train))})")
    want = max(1, int(round(fraction * len(train))))
    chosen = set()
    for g in sorted(groups, key=lambda g: hashlib.sha1(g.encode()).hexdigest()):
        if len(chosen) >= want:
            break
        chosen.update(groups[g])
    return [f for f in train if f in chosen]


@functools.lru_cache(maxsize=1)
def reference_skeleton():
    """The embedded data's 21-joint skeleton (every ``cmu`` training motion is put on it)."""
    from inbetween_jax.data.bvh import read_bvh
    return read_bvh(embedded_files("train")[0]).skeleton


def to_reference(motion, ref, fps: float, drop_tpose: bool = True):
    """``motion`` on ``ref``'s joints (same order), in ``ref``'s unit, without a leading T-pose frame, at
    ``fps``: a Motion (T', J_ref) whose skeleton is ``ref`` itself.

    Returns ``(motion, factor)`` with ``factor`` the reference units per file unit.  Raises ValueError naming
    the file when its bone offsets, converted, differ from ``ref``'s by more than 2 % of the leg length.
    """
    from inbetween_jax.data.bvh import Motion
    from inbetween_jax.data.features import leg_length
    from inbetween_jax.data.resample import resample_motion
    from inbetween_jax.data.retarget import match_joints, restrict
    if not motion.skeleton.same_topology(ref):
        motion = restrict(motion, match_joints(motion.skeleton, ref, motion.source), ref)
    from inbetween_jax.data.features import unit_factor
    factor = unit_factor(motion.skeleton, ref)
    offsets = np.asarray(motion.skeleton.offsets, np.float64) * factor
    err = float(np.abs(offsets[1:] - np.asarray(ref.offsets)[1:]).max())
    if err > 0.02 * leg_length(ref):
        raise ValueError(f"{motion.source}: its bone offsets differ from the embedded skeleton's by up to "
                         f"{err:.3g} units after scaling by {factor:g}; not the same body")
    q, p = np.asarray(motion.local_quats, np.float64), np.asarray(motion.local_pos, np.float64) * factor
    if drop_tpose and len(q) > 1 and float(np.abs(1.0 - np.abs(q[0, 1:, 0])).max()) < TPOSE_TOL:
        q, p = q[1:], p[1:]
    p[:, 1:] = np.asarray(ref.offsets)[None, 1:]            # exactly the reference bones (differ by < 2 %)
    out = resample_motion(Motion(ref, q, p, motion.frame_time, motion.source), fps)
    assert out.skeleton is ref and out.local_quats.shape[1] == ref.num_joints
    return out, factor


def _folder_label(path: str, shared: str) -> str:
    if os.path.dirname(os.path.abspath(path)) == os.path.abspath(EMBEDDED_DIR):
        return "embedded"
    return os.path.relpath(os.path.dirname(os.path.abspath(path)), shared)


def read_cmu_train(files: list, split: str, fps: float) -> tuple:
    """(motions on the embedded skeleton at ``fps``, the line saying what they are) for the ``cmu`` training
    files ``files`` (all of ``train``, or its ``val`` / ``fit`` part)."""
    from inbetween_jax.data.bvh import read_bvh
    from inbetween_jax.data.rig_transfer import transfer_rig
    from inbetween_jax.paths import shared_data_dir
    shared, ref = shared_data_dir(required=True), reference_skeleton()
    motions, frames, count, scaled, moved = [], Counter(), Counter(), Counter(), Counter()
    for f in progress(files, f"reading cmu {split} BVH"):
        label = _folder_label(f, shared)
        raw = read_bvh(f)
        if not _on_reference(f, ref.names) and _on_mb31_rig(f):
            raw = transfer_rig(raw, _body_template())
            moved[label] += 1
        m, factor = to_reference(raw, ref, fps)
        frames[label] += m.num_frames
        count[label] += 1
        if abs(factor - 1.0) > 0.05:
            scaled[label] = factor
        motions.append(m)
    parts = []
    for label in count:
        unit = f", x{scaled[label]:.4g} to the embedded unit" if label in scaled else ""
        if moved[label]:
            unit += (", retargeted by bone directions" if moved[label] == count[label]
                     else f", {moved[label]} retargeted by bone directions")
        parts.append(f"{label} {count[label]} files {frames[label] / fps / 60:.1f} min{unit}")
    what = "training on" if split == "train" else f"{split} split:"
    note = (f"data: cmu: {what} {len(files)} files, {sum(frames.values()) / fps / 60:.1f} min at {fps:g} fps "
            f"({'; '.join(parts)})")
    if split == "train":
        dropped = cmu_train_plan()[1]
        other = [os.path.basename(f) for f in dropped["other skeleton"]]
        note += (f"\ndata: cmu: left out {len(dropped['subjects 13/14'])} subject 13/14 trials (test subjects), "
                 f"{len(dropped['duplicates'])} duplicates of embedded trials, {len(other)} files on another "
                 f"skeleton ({', '.join(other) or 'none'})")
    return motions, note
