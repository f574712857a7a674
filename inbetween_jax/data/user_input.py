"""Users' inputs on the command line and from Python: keyframe specs, BVH files, skeleton checks, gap lists.

Every problem a user can cause raises :class:`~inbetween_jax.errors.UserError` (inputs named on the command
line) or ``ValueError`` (arrays given through the Python API) with one line naming the file or array and the
problem.  Nothing here writes files.
"""
from __future__ import annotations

import json
import os

import numpy as np

from inbetween_jax.errors import UserError

__all__ = ["split_spec", "read_motion", "read_keyframe", "pick_frame", "check_skeleton", "same_skeleton",
           "check_unit_quats", "read_json", "finite_or_fail", "merge_gaps", "parse_gaps",
           "resampled_gaps"]


def split_spec(spec: str, option: str) -> tuple:
    """``"a.bvh:12"`` -> ``("a.bvh", "12")``; ``"a.bvh"`` -> ``("a.bvh", None)``.

    A spec that exists as a path, or whose part after the last ':' holds a path separator, is not split.
    """
    if os.path.exists(spec) or ":" not in spec:
        return spec, None
    path, frame = spec.rsplit(":", 1)
    if "/" in frame or os.sep in frame:
        return spec, None
    if not path:
        raise UserError(f"{option} {spec!r}: missing file name before ':'")
    return path, frame


def read_motion(path: str):
    """read_bvh with every failure turned into a one-line UserError naming the file; what the tolerant reader
    let pass (motion rows beyond the ``Frames:`` line) is said in one ``inbetween: note:`` line on stderr."""
    import sys

    from inbetween_jax.data.bvh import BVHError, read_bvh
    notes = []
    try:
        motion = read_bvh(path, notes=notes)
    except BVHError as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"{path}: cannot read ({e.strerror or e})") from None
    for note in notes:
        print(f"inbetween: note: {note}", file=sys.stderr)
    return motion


def pick_frame(motion, path: str, frame, default: int, option: str) -> int:
    """Frame index of a keyframe spec: ``frame`` (str or None -> ``default``; negative default counts from
    the end), checked against the file's frame count."""
    n = motion.num_frames
    if frame is None:
        return default % n
    try:
        f = int(frame)
    except ValueError:
        raise UserError(f"{option} {path}:{frame}: frame {frame!r} is not an integer") from None
    if not 0 <= f < n:
        raise UserError(f"{option} {path}:{frame}: frame {f} is out of range ({path} has {n} frames: 0..{n - 1})")
    return f


def check_skeleton(skel, path: str, expected=None, num_joints=None, what: str = "the checkpoint") -> None:
    """Same joints (names, order, parents) as the checkpoint's skeleton ``expected`` (or at least
    ``num_joints`` joints when the training skeleton is unknown)."""
    want = expected.num_joints if expected is not None else num_joints
    if want is not None and skel.num_joints != want:
        raise UserError(f"{path}: skeleton has {skel.num_joints} joints but {what} was trained on {want}")
    if expected is None:
        return
    for j, (a, b) in enumerate(zip(skel.names, expected.names)):
        if a != b:
            raise UserError(f"{path}: joint {j} is {a!r} but {what} expects {b!r} (first differing joint)")
    for j, (a, b) in enumerate(zip(skel.parents, expected.parents)):
        if a != b:
            raise UserError(f"{path}: joint {skel.names[j]!r} has parent {skel.names[a]!r} but {what} "
                            f"expects {expected.names[b]!r}")


def same_skeleton(skel, path: str, ref, ref_path: str) -> None:
    """The file ``path`` is on the same rig (joint count, names, parents) as ``ref_path``, whose frames it pairs
    with; else a one-line error that names both files."""
    if skel.same_topology(ref):
        return
    if skel.num_joints != ref.num_joints:
        differs = f"its skeleton has {skel.num_joints} joints where the other keyframe's file has {ref.num_joints}"
    else:
        j = next((j for j, (a, b, pa, pb) in enumerate(zip(skel.names, ref.names, skel.parents, ref.parents))
                  if a != b or pa != pb), 0)
        def joint(sk):
            parent = sk.names[sk.parents[j]] if sk.parents[j] >= 0 else None
            return f"{sk.names[j]!r} (parent {parent!r})"
        differs = f"its joint {j} is {joint(skel)} where the other keyframe's file has {joint(ref)}"
    raise UserError(f"{path}: {differs} ({ref_path}); both keyframes' files must be on one rig")


def check_unit_quats(q, name: str, tol: float = 1e-3) -> np.ndarray:
    """(..., 4) finite unit quaternions as float64, else ValueError naming ``name``."""
    q = np.asarray(q, np.float64)
    if q.ndim == 0 or q.shape[-1] != 4:
        raise ValueError(f"{name}: expected quaternions of shape (..., 4), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError(f"{name}: quaternions hold NaN or inf")
    norm = np.linalg.norm(q, axis=-1)
    bad = np.argwhere(np.abs(norm - 1.0) > tol)
    if len(bad):
        i = tuple(int(v) for v in bad[0])
        raise ValueError(f"{name}: quaternion {i} has norm {norm[i]:.6g}, expected unit quaternions")
    return q


def read_json(path: str, what: str) -> dict:
    try:
        with open(path) as f:
            return json.load(f)
    except FileNotFoundError:
        raise UserError(f"{os.path.dirname(path) or '.'}: no {os.path.basename(path)} ({what})") from None
    except (OSError, ValueError) as e:
        raise UserError(f"{path}: unreadable run metadata ({e})") from None


def finite_or_fail(what: str, *arrays) -> None:
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise UserError(f"{what}: the model produced NaN or inf (is the checkpoint diverged?)")


def merge_gaps(gaps) -> tuple:
    """Sort ``[(start, stop), ...]`` gaps (stop exclusive) and merge overlapping or touching ones.

    Returns ``(merged, message)``: the union as a sorted list of disjoint, non-touching gaps, and a line
    such as ``"overlapping gaps merged into 20:50"`` when anything was merged (None otherwise).
    """
    merged, groups = [], []
    for a, b in sorted((int(a), int(b)) for a, b in gaps):
        if merged and a <= merged[-1][1]:
            groups[-1].append((a, b))
            merged[-1] = (merged[-1][0], max(merged[-1][1], b))
        else:
            merged.append((a, b))
            groups.append([(a, b)])
    joined = [(m, g) for m, g in zip(merged, groups) if len(g) > 1]
    if not joined:
        return merged, None
    overlap = any(g[i + 1][0] < max(e for _, e in g[:i + 1]) for _, g in joined for i in range(len(g) - 1))
    touch = any(g[i + 1][0] == max(e for _, e in g[:i + 1]) for _, g in joined for i in range(len(g) - 1))
    kind = " or ".join(k for k, on in (("overlapping", overlap), ("touching", touch)) if on)
    return merged, f"{kind} gaps merged into {', '.join(f'{a}:{b}' for (a, b), _ in joined)}"


def parse_gaps(text: str, num_frames=None, path: str = "", notes=None) -> list:
    """``"100:160,300:420"`` -> ``[(100, 160), (300, 420)]`` (stop exclusive), checked against the clip.

    Overlapping or touching gaps are merged (:func:`merge_gaps`); when ``notes`` is a list, the line saying
    so (``"--gaps 20:40,30:50: overlapping gaps merged into 20:50"``) is appended to it for the caller to print.
    """
    gaps = []
    for part in text.split(","):
        bits = part.strip().split(":")
        try:
            if len(bits) != 2:
                raise ValueError
            a, b = int(bits[0]), int(bits[1])
        except ValueError:
            raise UserError(f"--gaps {text!r}: {part.strip()!r} is not START:STOP with integer frames") from None
        if a < 0 or b <= a:
            raise UserError(f"--gaps {text!r}: gap {a}:{b} must have 0 <= START < STOP")
        gaps.append((a, b))
    if num_frames is not None:
        for a, b in gaps:
            if b > num_frames:
                raise UserError(f"--gaps {text!r}: gap {a}:{b} goes beyond the end of {path} ({num_frames} frames)")
    gaps, message = merge_gaps(gaps)
    if num_frames is not None and gaps == [(0, num_frames)]:
        raise UserError(f"--gaps {text!r}: the gaps cover all {num_frames} frames of {path}; nothing is left "
                        "to fill from")
    if message and notes is not None:
        notes.append(f"--gaps {text}: {message}")
    return gaps


def resampled_gaps(gaps, ratio: float, num_frames: int, text: str, path: str) -> list:
    """Gaps in a file's frames -> gaps in its resampled frames (``ratio`` = new fps / file fps,
    :func:`~inbetween_jax.data.resample.resample_motion`'s frame times ``k / ratio``): every resampled frame
    interpolated from a gap frame is in the gap, so no known frame reads one: the gap starts at the first frame
    after file time ``a - 1`` and ends at the first frame at or after file time ``b``.  A gap that falls between
    two resampled frames keeps the nearest one; gaps are merged again where they now touch."""
    from inbetween_jax.data.resample import FRAME_TOL
    out = []
    for a, b in gaps:
        lo = 0 if a == 0 else int(np.floor((a - 1) * ratio + FRAME_TOL)) + 1
        hi = int(np.ceil(b * ratio - FRAME_TOL))
        if hi <= lo:                                   # between two resampled frames: the nearest one
            lo = int(round(0.5 * (a + b) * ratio))
            hi = lo + 1
        lo = min(lo, num_frames - 1)
        out.append((lo, min(max(hi, lo + 1), num_frames)))
    out, _ = merge_gaps(out)
    if out == [(0, num_frames)]:
        raise UserError(f"--gaps {text!r}: after resampling the gaps cover all {num_frames} frames of {path}; "
                        "nothing is left to fill from")
    return out


def read_keyframe(spec: str, option: str, default: int, cache: dict) -> tuple:
    """``"a.bvh:12"`` -> ``(path, Motion, frame)``; files are read once per ``cache`` (path -> Motion)."""
    path, frame = split_spec(spec, option)
    if path not in cache:
        cache[path] = read_motion(path)
    return path, cache[path], pick_frame(cache[path], path, frame, default, option)
