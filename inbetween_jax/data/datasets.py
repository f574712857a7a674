"""One entry point for every data source: LaFAN1 folders, the embedded CMU default, any BVH folder.

``source`` is resolved as: an explicit argument, else ``$LAFAN1_DIR`` if set, else ``"embedded"``.

* ``"embedded"`` -- the real CMU mocap shipped in ``inbetween_jax/assets/cmu30`` (30 Hz, 21 joints);
  subjects 13 and 14 are the test split, the rest train.
* a folder of LaFAN1 files (``<action>_subjectN.bvh``) -- the official LaFAN1 splits and windows.
* any other folder of BVH files on one skeleton -- ``<stem>`` sorted, the last 20 % test.

Windows are prepared once into an ``.npz`` cache keyed by the files' names, sizes and mtimes and the
window settings, under ``$INBETWEEN_JAX_CACHE`` (default ``~/.cache/inbetween_jax``).
"""
from __future__ import annotations

import hashlib
import json
import os
from typing import Optional

import numpy as np

from inbetween_jax.data import lafan1
from inbetween_jax.data.bvh import Motion, read_bvh
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.data.windows import MotionWindows, windows_from_motions

EMBEDDED_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "assets", "cmu30")
EMBEDDED_TEST_PREFIXES = ("13_", "14_")
CACHE_VERSION = 1
GENERIC_CONTACT_VELFACTOR = 1.0  # squared cm per frame


def resolve_source(source: Optional[str] = None) -> str:
    """The data source to use: ``source``, else ``$LAFAN1_DIR``, else ``"embedded"``."""
    if source:
        return source
    return os.environ.get("LAFAN1_DIR") or "embedded"


def is_lafan1(source: str) -> bool:
    return source != "embedded" and os.path.isdir(source) and any(
        lafan1._NAME.match(f) for f in os.listdir(source))


def split_files(source: str, split: str) -> list:
    """BVH paths of ``split`` (``train`` / ``test`` / ``benchmark``) for ``source``."""
    if split not in ("train", "test", "benchmark"):
        raise ValueError(f"unknown split {split!r}; choose train, test or benchmark")
    if source == "embedded" or not is_lafan1(source):
        folder = EMBEDDED_DIR if source == "embedded" else source
        if not os.path.isdir(folder):
            raise FileNotFoundError(f"data folder {folder!r} does not exist")
        files = sorted(os.path.join(folder, f) for f in os.listdir(folder) if f.lower().endswith(".bvh"))
        if not files:
            raise FileNotFoundError(f"no .bvh files in {folder!r}")
        if source == "embedded":
            test = [f for f in files if os.path.basename(f).startswith(EMBEDDED_TEST_PREFIXES)]
        else:
            test = files[int(round(len(files) * 0.8)):] if len(files) > 1 else files
        return test if split != "train" else [f for f in files if f not in test]
    return lafan1.lafan1_files(source, lafan1.split_spec(split)["subjects"])


def window_settings(source: str, split: str) -> dict:
    """Window length, offset, past frames and root forward axis for a split of a source."""
    spec = lafan1.split_spec(split)
    if is_lafan1(source):
        forward, velfactor = lafan1.ROOT_FORWARD_AXIS, lafan1.CONTACT_VELFACTOR
    else:
        # forward inferred from the skeleton; the official 0.02 cm^2/frame^2 contact threshold labels
        # almost no CMU stance frames (their ankles pivot ~0.5-1 cm per frame at 30 Hz), so use 1 cm/frame
        forward, velfactor = None, GENERIC_CONTACT_VELFACTOR
    return dict(window=spec["window"], offset=spec["offset"], n_past=lafan1.N_PAST, forward_axis=forward,
                contact_velfactor=velfactor)


def load_motions(source: Optional[str] = None, split: str = "train") -> list:
    """Whole motions (list of :class:`Motion`) of a split, all on one skeleton."""
    source = resolve_source(source)
    motions = [read_bvh(f) for f in _progress(split_files(source, split), f"reading {split} BVH")]
    first = motions[0]
    for m in motions[1:]:
        if not m.skeleton.same_topology(first.skeleton):
            raise ValueError(f"{m.source}: its skeleton ({m.skeleton.num_joints} joints) differs from "
                             f"{first.source} ({first.skeleton.num_joints} joints); use one skeleton per folder")
    return motions


def load_dataset(source: Optional[str] = None, split: str = "train", window: Optional[int] = None,
                 offset: Optional[int] = None, use_cache: bool = True) -> MotionWindows:
    """Canonicalised windows of a split (see module docstring), cached as npz.

    ``window`` / ``offset`` override the split's defaults (50/20 train and test, 65/40 benchmark).
    """
    source = resolve_source(source)
    files = split_files(source, split)
    ws = window_settings(source, split)
    if window is not None:
        ws["window"] = int(window)
    if offset is not None:
        ws["offset"] = int(offset)
    key = _cache_key(files, ws)
    path = os.path.join(cache_dir(), "windows", f"{split}-{key}.npz")
    if use_cache and os.path.exists(path):
        try:
            return _load_npz(path)
        except (OSError, ValueError, KeyError):
            pass  # a damaged cache is rebuilt below
    motions = load_motions(source, split)
    forward = ws["forward_axis"] or tuple(motions[0].skeleton.forward_axis())
    data = windows_from_motions(motions, ws["window"], ws["offset"], ws["n_past"], forward,
                                ws["contact_velfactor"])
    if use_cache:
        _save_npz(path, data)
    return data


def cache_dir() -> str:
    return os.path.abspath(os.path.expanduser(os.environ.get("INBETWEEN_JAX_CACHE", "~/.cache/inbetween_jax")))


def _cache_key(files, settings) -> str:
    h = hashlib.sha1(json.dumps([CACHE_VERSION, settings], sort_keys=True, default=list).encode())
    for f in files:
        st = os.stat(f)
        h.update(f"{os.path.abspath(f)}|{st.st_size}|{st.st_mtime_ns}".encode())
    return h.hexdigest()[:16]


def _save_npz(path: str, data: MotionWindows) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + f".tmp{os.getpid()}.npz"
    np.savez(tmp, local_quats=data.local_quats, root_pos=data.root_pos, contacts=data.contacts,
             seq_names=np.asarray(data.seq_names), fps=np.float64(data.fps),
             skeleton=np.asarray(json.dumps(data.skeleton.to_dict())))
    os.replace(tmp, path)


def _load_npz(path: str) -> MotionWindows:
    with np.load(path, allow_pickle=False) as z:
        skel = Skeleton.from_dict(json.loads(str(z["skeleton"])))
        return MotionWindows(z["local_quats"], z["root_pos"], z["contacts"], skel, [str(s) for s in z["seq_names"]],
                             float(z["fps"]))


def _progress(items, desc):
    try:
        from tqdm import tqdm
        return tqdm(items, desc=desc, leave=False, disable=len(items) < 4)
    except ImportError:  # pragma: no cover
        return items


__all__ = ["Motion", "MotionWindows", "load_dataset", "load_motions", "resolve_source", "split_files"]
