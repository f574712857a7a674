"""BVH reading and writing for any skeleton and any channel order.

``read_bvh`` returns a :class:`Motion` with local quaternions (T, J, 4) and local positions (T, J, 3)
in float64. Malformed files raise :class:`BVHError` whose message names the file and line.
``write_bvh`` writes a file that ``read_bvh`` reads back to 1e-4 (Euler angles written with 6 decimals).
"""
from __future__ import annotations

import dataclasses
import os
import tempfile
from typing import Optional

import numpy as np

from inbetween_jax.data.skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton
from inbetween_jax.geometry.quaternion import quat_fix_sign_np, quat_from_euler, quat_normalize, quat_to_euler

KNOWN_CHANNELS = POSITION_CHANNELS + ROTATION_CHANNELS


class BVHError(ValueError):
    """A BVH file could not be read; the message is ``"<file>:<line>: <problem>"``."""

    def __init__(self, path, line: Optional[int], problem: str):
        self.path, self.line, self.problem = str(path), line, problem
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {problem}")


@dataclasses.dataclass
class Motion:
    """An animation on a skeleton.

    local_quats: (T, J, 4) float64 local rotations (w, x, y, z), sign-continuous over time.
    local_pos:   (T, J, 3) float64 local positions (row 0: root's global position, others: offsets,
                 or the animated values for joints that have position channels).
    frame_time:  seconds per frame.
    """

    skeleton: Skeleton
    local_quats: np.ndarray
    local_pos: np.ndarray
    frame_time: float
    source: str = ""

    @property
    def num_frames(self) -> int:
        return int(self.local_quats.shape[0])

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    @property
    def root_pos(self) -> np.ndarray:
        """(T, 3) root trajectory."""
        return self.local_pos[:, 0]

    def slice(self, start: int, stop: int, step: int = 1) -> "Motion":
        return dataclasses.replace(self, local_quats=self.local_quats[start:stop:step],
                                   local_pos=self.local_pos[start:stop:step],
                                   frame_time=self.frame_time * step)


def _tokenize(path: str):
    try:
        with open(path, "r", encoding="utf-8", errors="strict") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise BVHError(path, None, "file not found") from None
    except IsADirectoryError:
        raise BVHError(path, None, "is a directory, not a BVH file") from None
    except UnicodeDecodeError as e:
        raise BVHError(path, None, f"not a text file ({e.reason} at byte {e.start})") from None
    return text.splitlines()


def _parse_hierarchy(path, lines):
    """Parse HIERARCHY up to MOTION. Returns (Skeleton, index of the line after MOTION)."""
    names, parents, offsets, channels, end_sites = [], [], [], [], []
    stack = []  # joint index or "end"
    pending = None  # joint or end site waiting for "{"
    i = 0
    while i < len(lines) and not lines[i].strip():
        i += 1
    if i >= len(lines) or lines[i].strip() != "HIERARCHY":
        raise BVHError(path, i + 1 if i < len(lines) else None, "missing HIERARCHY header")
    i += 1
    while i < len(lines):
        lineno, words = i + 1, lines[i].split()
        i += 1
        if not words:
            continue
        key = words[0]
        if key in ("ROOT", "JOINT"):
            if len(words) < 2:
                raise BVHError(path, lineno, f"{key} without a name")
            if key == "ROOT" and names:
                raise BVHError(path, lineno, "more than one ROOT is not supported")
            if key == "JOINT" and (not stack or stack[-1] == "end"):
                raise BVHError(path, lineno, "JOINT outside a joint block")
            names.append(" ".join(words[1:]))
            parents.append(stack[-1] if stack else -1)
            offsets.append(None)
            channels.append(())
            pending = len(names) - 1
        elif key == "End" and len(words) > 1 and words[1] == "Site":
            if not stack or stack[-1] == "end":
                raise BVHError(path, lineno, "End Site outside a joint block")
            end_sites.append([stack[-1], None])
            pending = "end"
        elif key == "{":
            if pending is None:
                raise BVHError(path, lineno, "unexpected '{'")
            stack.append(pending)
            pending = None
        elif key == "}":
            if not stack:
                raise BVHError(path, lineno, "unbalanced '}'")
            stack.pop()
        elif key == "OFFSET":
            if not stack:
                raise BVHError(path, lineno, "OFFSET outside a joint block")
            try:
                vals = np.array([float(w) for w in words[1:]], np.float64)
            except ValueError:
                raise BVHError(path, lineno, f"non-numeric OFFSET {' '.join(words[1:])!r}") from None
            if vals.shape != (3,) or not np.all(np.isfinite(vals)):
                raise BVHError(path, lineno, f"OFFSET needs 3 finite numbers, got {' '.join(words[1:])!r}")
            if stack[-1] == "end":
                end_sites[-1][1] = vals
            else:
                offsets[stack[-1]] = vals
        elif key == "CHANNELS":
            if not stack or stack[-1] == "end":
                raise BVHError(path, lineno, "CHANNELS outside a joint block")
            try:
                n = int(words[1])
            except (IndexError, ValueError):
                raise BVHError(path, lineno, "CHANNELS needs a count") from None
            chans = tuple(words[2:])
            if len(chans) != n:
                raise BVHError(path, lineno, f"CHANNELS says {n} but lists {len(chans)} names")
            for c in chans:
                if c not in KNOWN_CHANNELS:
                    raise BVHError(path, lineno, f"unknown channel name {c!r} (expected one of {KNOWN_CHANNELS})")
            rot = [c for c in chans if c in ROTATION_CHANNELS]
            if len(rot) not in (0, 3) or len(set(rot)) != len(rot):
                raise BVHError(path, lineno, f"rotation channels must be three distinct axes, got {rot}")
            channels[stack[-1]] = chans
        elif key == "MOTION":
            if stack:
                raise BVHError(path, lineno, "MOTION before every '{' was closed")
            break
        else:
            raise BVHError(path, lineno, f"unexpected {key!r} in HIERARCHY")
    else:
        raise BVHError(path, len(lines), "file ends before the MOTION section")
    if not names:
        raise BVHError(path, None, "no ROOT joint")
    for j, o in enumerate(offsets):
        if o is None:
            raise BVHError(path, None, f"joint {names[j]!r} has no OFFSET")
    dup = next((n for k, n in enumerate(names) if n in names[:k]), None)
    if dup is not None:
        raise BVHError(path, None, f"joint name {dup!r} appears more than once")
    skel = Skeleton(tuple(names), tuple(parents), np.stack(offsets), tuple(channels),
                    tuple((p, o if o is not None else np.zeros(3)) for p, o in end_sites))
    return skel, i


def _parse_motion(path, lines, start_line, skel):
    """Parse Frames / Frame Time / data. Returns (values (T, C) float64, frame_time)."""
    i = start_line
    header = {}
    for key in ("Frames:", "Frame Time:"):
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines) or not lines[i].strip().startswith(key):
            raise BVHError(path, i + 1 if i < len(lines) else len(lines), f"expected '{key}' line")
        try:
            header[key] = float(lines[i].strip()[len(key):])
        except ValueError:
            raise BVHError(path, i + 1, f"bad value in {lines[i].strip()!r}") from None
        i += 1
    frames, frame_time = header["Frames:"], header["Frame Time:"]
    if not np.isfinite(frames) or frames != int(frames) or frames < 1:
        raise BVHError(path, start_line + 1, f"Frames must be a positive integer, got {lines[start_line].strip()!r}")
    if not np.isfinite(frame_time) or frame_time <= 0:
        raise BVHError(path, start_line + 2, f"Frame Time must be positive, got {frame_time}")
    frames, nchan = int(frames), skel.num_channels
    data = [(k + 1, ln) for k, ln in enumerate(lines[i:], start=i) if ln.strip()]
    if len(data) < frames:
        raise BVHError(path, len(lines), f"truncated MOTION block: header says {frames} frames, found {len(data)}")
    if len(data) > frames:
        raise BVHError(path, data[frames][0], f"more frame lines than the {frames} in the header")
    rows = [ln.split() for _, ln in data]
    for (lineno, _), r in zip(data, rows):
        if len(r) != nchan:
            raise BVHError(path, lineno, f"frame has {len(r)} values, the hierarchy declares {nchan} channels")
    try:
        values = np.array(rows, dtype=np.float64)
    except ValueError:
        for (lineno, _), r in zip(data, rows):
            for col, w in enumerate(r):
                try:
                    float(w)
                except ValueError:
                    raise BVHError(path, lineno, f"non-numeric value {w!r} in column {col + 1}") from None
        raise
    bad = ~np.isfinite(values)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise BVHError(path, data[row][0], f"non-finite value {rows[row][col]!r} in column {col + 1}")
    return values, frame_time


def read_bvh(path, start: Optional[int] = None, end: Optional[int] = None) -> Motion:
    """Read a BVH file (any skeleton, any channel order) into a :class:`Motion` (frames [start, end))."""
    path = os.fspath(path)
    lines = _tokenize(path)
    skel, motion_line = _parse_hierarchy(path, lines)
    values, frame_time = _parse_motion(path, lines, motion_line, skel)
    values = values[start:end]
    if values.shape[0] == 0:
        raise BVHError(path, None, f"frame range [{start}, {end}) selects no frames")
    t, j = values.shape[0], skel.num_joints
    euler = np.zeros((t, j, 3))
    pos = np.broadcast_to(skel.offsets, (t, j, 3)).copy()
    col = 0
    for k, chans in enumerate(skel.channels):
        for c in chans:
            if c in POSITION_CHANNELS:
                pos[:, k, POSITION_CHANNELS.index(c)] = values[:, col]
            col += 1
        rot_cols = [col - len(chans) + n for n, c in enumerate(chans) if c in ROTATION_CHANNELS]
        if rot_cols:
            euler[:, k] = values[:, rot_cols]
    quats = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (t, j, 1))
    for k in range(j):
        order = skel.rotation_order(k)
        if order:
            quats[:, k] = quat_from_euler(np.radians(euler[:, k]), order)
    return Motion(skel, quat_fix_sign_np(quats), pos, frame_time, source=path)


def motion_to_channels(motion: Motion) -> np.ndarray:
    """(T, C) BVH channel values (degrees for rotations) in the skeleton's channel order."""
    skel = motion.skeleton
    if motion.local_quats.shape[1:] != (skel.num_joints, 4):
        raise ValueError(f"motion has {motion.local_quats.shape[1]} joints, skeleton has {skel.num_joints}")
    q = quat_normalize(np.asarray(motion.local_quats, np.float64), eps=0.0)
    cols = []
    for k, chans in enumerate(skel.channels):
        order = skel.rotation_order(k)
        euler = np.degrees(quat_to_euler(q[:, k], order)) if order else None
        for c in chans:
            if c in POSITION_CHANNELS:
                cols.append(motion.local_pos[:, k, POSITION_CHANNELS.index(c)])
            else:
                cols.append(euler[:, order.index(c[0].lower())])
    return np.stack(cols, axis=1) if cols else np.zeros((motion.num_frames, 0))


def write_bvh(path, motion: Motion, decimals: int = 6) -> None:
    """Write ``motion`` as BVH on its skeleton. Atomic: a temporary file is renamed into place.

    Raises ValueError (before touching ``path``) for non-finite values or shape mismatches.
    """
    path = os.fspath(path)
    if not (np.all(np.isfinite(motion.local_quats)) and np.all(np.isfinite(motion.local_pos))):
        raise ValueError(f"{path}: refusing to write non-finite motion values")
    values = motion_to_channels(motion)
    skel = motion.skeleton
    out = ["HIERARCHY"]
    ends = {}
    for p, o in skel.end_sites:
        ends.setdefault(p, []).append(o)

    def emit(k, depth):
        ind = "\t" * depth
        out.append(f"{ind}{'ROOT' if k == 0 else 'JOINT'} {skel.names[k]}")
        out.append(f"{ind}{{")
        o = skel.offsets[k]
        out.append(f"{ind}\tOFFSET {o[0]:.6f} {o[1]:.6f} {o[2]:.6f}")
        if skel.channels[k]:
            out.append(f"{ind}\tCHANNELS {len(skel.channels[k])} {' '.join(skel.channels[k])}")
        for c in skel.children(k):
            emit(c, depth + 1)
        for e in ends.get(k, []):
            out.extend([f"{ind}\tEnd Site", f"{ind}\t{{", f"{ind}\t\tOFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}",
                    f"{ind}\t}}"])
        out.append(f"{ind}}}")

    emit(0, 0)
    out += ["MOTION", f"Frames: {values.shape[0]}", f"Frame Time: {motion.frame_time:.8f}"]
    fmt = f"%.{decimals}f"
    body = "\n".join(" ".join(fmt % v for v in row) for row in values)
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=directory, suffix=".bvh.tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write("\n".join(out) + "\n" + body + "\n")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
