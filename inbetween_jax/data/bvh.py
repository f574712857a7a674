"""BVH reading and writing for any skeleton and any channel order.

``read_bvh`` returns a :class:`Motion` with local quaternions (T, J, 4) and local positions (T, J, 3)
in float64. Malformed files raise :class:`BVHError` whose message names the file and line; the variants of the
format that common exporters write are accepted (see :mod:`inbetween_jax.data.bvh_parse`).
``write_bvh`` writes a file that ``read_bvh`` reads back to 1e-4 (Euler angles written with 6 decimals).
"""
from __future__ import annotations

import dataclasses
import os
import stat
import tempfile
from typing import Optional

import numpy as np

from inbetween_jax.data.bvh_parse import KNOWN_CHANNELS, BVHError  # noqa: F401  (re-exported)
from inbetween_jax.data.bvh_parse import parse_hierarchy, parse_motion, read_lines
from inbetween_jax.data.skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton
from inbetween_jax.geometry.quaternion import quat_fix_sign_np, quat_from_euler, quat_normalize, quat_to_euler


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

    def global_positions(self) -> np.ndarray:
        """(T, J, 3) world joint positions (forward kinematics, float64)."""
        from inbetween_jax.geometry.kinematics import forward_kinematics
        return forward_kinematics(np.asarray(self.local_quats, np.float64), np.asarray(self.local_pos, np.float64),
                                  self.skeleton.parents)[1]

    def positions_of(self, local_quats, root_pos) -> np.ndarray:
        """(..., J, 3) world joint positions of other rotations ``local_quats`` (..., J, 4) and root positions
        ``root_pos`` (..., 3) on this motion's skeleton and bone offsets (a fill of some of its frames, say)."""
        from inbetween_jax.geometry.kinematics import forward_kinematics, local_positions
        return forward_kinematics(np.asarray(local_quats, np.float64),
                                  local_positions(np.asarray(root_pos, np.float64), self.local_pos[0]),
                                  self.skeleton.parents)[1]

    def slice(self, start: int, stop: int, step: int = 1) -> "Motion":
        return dataclasses.replace(self, local_quats=self.local_quats[start:stop:step],
                                   local_pos=self.local_pos[start:stop:step],
                                   frame_time=self.frame_time * step)

    def mirrored(self, world_axis: int = 0) -> "Motion":
        """The left-right mirror image in the world plane with normal ``world_axis`` (a floor axis): left and
        right joints (``Skeleton.mirror_map``) swap, every position is reflected
        (:func:`inbetween_jax.geometry.mirror.mirror_pose`).  Raises ValueError (one line) on a rig without
        left/right joints or whose rest pose is not symmetric."""
        from inbetween_jax.geometry.mirror import mirror_pose, rest_side_axis
        twin = self.skeleton.mirror_map()
        axis = rest_side_axis(self.skeleton.offsets, twin)
        q, _, lp = mirror_pose(self.local_quats, self.root_pos, twin, axis, world_axis, self.local_pos)
        return dataclasses.replace(self, local_quats=q, local_pos=lp)

    def scaled(self, factor: float) -> "Motion":
        """The same motion in another length unit: bone offsets and local positions times ``factor``."""
        return dataclasses.replace(self, local_pos=self.local_pos * factor,
                                   skeleton=dataclasses.replace(self.skeleton, offsets=self.skeleton.offsets * factor))


def read_bvh(path, start: Optional[int] = None, end: Optional[int] = None, notes: Optional[list] = None) -> Motion:
    """Read a BVH file (any skeleton, any channel order) into a :class:`Motion` (frames [start, end)).

    Frames beyond the count in the ``Frames:`` line are ignored (``notes``, a list, gets a line saying so);
    fewer frames than it declares raise :class:`BVHError`. The exporter variants accepted are listed in
    :mod:`inbetween_jax.data.bvh_parse`.
    """
    path = os.fspath(path)
    lines = read_lines(path)
    skel, motion_line = parse_hierarchy(path, lines)
    values, frame_time = parse_motion(path, lines, motion_line, skel.num_channels, notes)
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


def _umask() -> int:
    """The process umask, read without changing it where the platform allows."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _mode_for(path: str) -> int:
    """Permission bits ``open(path, "w")`` would leave: the existing file's, else 0o666 less the umask."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~_umask()


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
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            os.fchmod(fh.fileno(), _mode_for(path))  # mkstemp makes 0600; give the mode open() would
            fh.write("\n".join(out) + "\n" + body + "\n")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
