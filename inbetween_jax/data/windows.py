"""Fixed-length windows over motions, and the LaFAN1 benchmark's canonicalisation.

:class:`MotionWindows` is the one batch container every dataset, model and benchmark uses.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from inbetween_jax.data.bvh import Motion
from inbetween_jax.data.features import foot_contacts
from inbetween_jax.data.skeleton import Skeleton
from inbetween_jax.geometry.mirror import MIRROR_TAG, mirror_pose, rest_side_axis
from inbetween_jax.geometry.kinematics import forward_kinematics, inverse_kinematics, local_positions
from inbetween_jax.geometry.quaternion import quat_between, quat_fix_sign_np, quat_inv, quat_mul, quat_rotate


@dataclasses.dataclass
class MotionWindows:
    """N windows of T frames on one skeleton.

    local_quats: (N, T, J, 4) float32 local rotations (w, x, y, z), sign-continuous in time.
    root_pos:    (N, T, 3) float32 root position (centred / rotated as the dataset says).
    contacts:    (N, T, 4) float32 foot contacts (left ankle, left toe, right ankle, right toe).
    skeleton:    the shared :class:`Skeleton` (``skeleton.offsets`` are the bone offsets used by FK).
    seq_names:   N source names (``"<file stem>@<first frame>"``).
    fps:         frame rate.
    unit_scale:  centimetres per position unit (1.0 for LaFAN1 and the embedded data; see
                 :func:`inbetween_jax.data.features.detect_unit_scale`). Positions stay in the files' units.
    """

    local_quats: np.ndarray
    root_pos: np.ndarray
    contacts: np.ndarray
    skeleton: Skeleton
    seq_names: list
    fps: float
    unit_scale: float = 1.0

    def __len__(self) -> int:
        return int(self.local_quats.shape[0])

    @property
    def window(self) -> int:
        return int(self.local_quats.shape[1])

    @property
    def offsets(self) -> np.ndarray:
        """(J, 3) float32 bone offsets."""
        return self.skeleton.offsets.astype(np.float32)

    @property
    def parents(self) -> tuple:
        return self.skeleton.parents

    def local_pos(self) -> np.ndarray:
        """(N, T, J, 3) local positions (root position + offsets)."""
        return local_positions(self.root_pos, self.offsets)

    def global_pose(self):
        """FK in NumPy: returns (global_quats (N, T, J, 4), global_pos (N, T, J, 3)) float32."""
        gq, gp = forward_kinematics(self.local_quats.astype(np.float64), self.local_pos().astype(np.float64),
                                    self.parents)
        return gq.astype(np.float32), gp.astype(np.float32)

    def take(self, index) -> "MotionWindows":
        """Subset by an index array or slice."""
        idx = np.arange(len(self))[index]
        return dataclasses.replace(self, local_quats=self.local_quats[idx], root_pos=self.root_pos[idx],
                                   contacts=self.contacts[idx], seq_names=[self.seq_names[i] for i in idx])

    def crop(self, length: int) -> "MotionWindows":
        """Keep the first ``length`` frames of every window."""
        if not 1 <= length <= self.window:
            raise ValueError(f"cannot crop {self.window}-frame windows to {length} frames")
        return dataclasses.replace(self, local_quats=self.local_quats[:, :length],
                                   root_pos=self.root_pos[:, :length], contacts=self.contacts[:, :length])

    def reversed(self) -> "MotionWindows":
        """The same windows played backwards (training data of the backward generator)."""
        return dataclasses.replace(self, local_quats=self.local_quats[:, ::-1].copy(),
                                   root_pos=self.root_pos[:, ::-1].copy(), contacts=self.contacts[:, ::-1].copy(),
                                   seq_names=[n + ":reversed" for n in self.seq_names])

    def mirrored(self, world_axis: int = 0) -> "MotionWindows":
        """The left-right mirror image of every window in the world plane with normal ``world_axis`` (a floor
        axis): left and right joints and foot contacts swap (:func:`inbetween_jax.geometry.mirror.mirror_pose`);
        names gain :data:`MIRROR_TAG`.  Raises ValueError (one line) on a rig without left/right joints or
        whose rest pose is not symmetric."""
        twin = self.skeleton.mirror_map()
        q, r = mirror_pose(self.local_quats, self.root_pos, twin, rest_side_axis(self.skeleton.offsets, twin),
                           world_axis)
        return dataclasses.replace(self, local_quats=q.astype(np.float32), root_pos=r.astype(np.float32),
                                   contacts=self.contacts[..., [2, 3, 0, 1]].copy(),
                                   seq_names=[n + MIRROR_TAG for n in self.seq_names])

    def batch(self, index) -> dict:
        """A dict of float32 arrays for a training step (index: int array of window ids)."""
        return {"local_quats": self.local_quats[index], "root_pos": self.root_pos[index],
                "contacts": self.contacts[index]}

    @staticmethod
    def concatenate(parts: Sequence["MotionWindows"]) -> "MotionWindows":
        if not parts:
            raise ValueError("no windows to concatenate")
        first = parts[0]
        for p in parts[1:]:
            if not p.skeleton.same_topology(first.skeleton) or p.window != first.window:
                raise ValueError("cannot concatenate windows of different skeletons or lengths")
            if p.unit_scale != first.unit_scale or abs(p.fps - first.fps) > 1e-3:
                raise ValueError(f"cannot concatenate windows in different units or frame rates "
                                 f"({first.unit_scale} vs {p.unit_scale} cm per unit, {first.fps} vs {p.fps} fps)")
        return MotionWindows(np.concatenate([p.local_quats for p in parts]),
                             np.concatenate([p.root_pos for p in parts]),
                             np.concatenate([p.contacts for p in parts]), first.skeleton,
                             sum((p.seq_names for p in parts), []), first.fps, first.unit_scale)


def window_starts(num_frames: int, window: int, offset: int) -> list:
    """Start frames of the official LaFAN1 sliding windows: ``i = 0, offset, ...`` while ``i + window < T``.

    (The strict ``<`` follows the official ``extract.get_lafan1_set``.)
    """
    if window < 1 or offset < 1:
        raise ValueError(f"window and offset must be >= 1, got {window}, {offset}")
    return list(range(0, max(num_frames - window, 0), offset))


def keyframe_pairs(motion: Motion, lengths=(10, 30, 50), stride: int = 40):
    """Every ``stride`` frames of ``motion``, a keyframe pair around each gap of ``n`` frames in ``lengths``.
    Yields ``(n, k0 (B,), k1 (B,), truth (B, n, J, 3))``: the start and end keyframes (``k1 = k0 + n + 1``) and the
    global joint positions of the frames between them; lengths the motion is too short for are skipped."""
    positions = forward_kinematics(motion.local_quats, motion.local_pos, motion.skeleton.parents)[1]
    for n in lengths:
        k0 = np.arange(0, motion.num_frames - n - 2, stride)
        if len(k0):
            yield n, k0, k0 + n + 1, np.stack([positions[i + 1:i + n + 1] for i in k0])


def canonicalize(local_quats, root_pos, skeleton: Skeleton, n_past: int, forward_axis=(0.0, 1.0, 0.0),
                 target_dir=(1.0, 0.0, 0.0)):
    """Centre windows in XZ on their mean root position and turn them to face ``target_dir`` at frame
    ``n_past - 1``, exactly as the official LaFAN1 ``extract.get_lafan1_set`` / ``rotate_at_frame``.

    ``forward_axis`` is the root's local axis taken as "facing" (LaFAN1 hips: +Y).
    local_quats (N, T, J, 4), root_pos (N, T, 3) float64 -> the same, transformed.
    """
    root = np.array(root_pos, np.float64, copy=True)
    xz = root[:, :, [0, 2]].mean(axis=1, keepdims=True)
    root[:, :, 0] -= xz[..., 0]
    root[:, :, 2] -= xz[..., 1]
    gq, gp = forward_kinematics(local_quats, local_positions(root, skeleton.offsets), skeleton.parents)
    key = gq[:, n_past - 1: n_past, 0:1, :]
    fwd = np.array([1.0, 0.0, 1.0]) * quat_rotate(key, np.broadcast_to(np.asarray(forward_axis), key.shape[:-1] + (3,)))
    fwd = fwd / np.linalg.norm(fwd, axis=-1, keepdims=True)
    yrot = quat_between(np.broadcast_to(np.asarray(target_dir, np.float64), fwd.shape), fwd)
    inv = quat_inv(yrot)
    new_gq = quat_mul(inv, gq)
    new_gp = quat_rotate(np.broadcast_to(inv, gp.shape[:-1] + (4,)), gp)
    lq, lp = inverse_kinematics(new_gq, new_gp, skeleton.parents)
    return quat_fix_sign_np(lq, axis=1), lp[:, :, 0]


def windows_from_motions(motions: Sequence[Motion], window: int, offset: int, n_past: int = 10,
                         forward_axis=(0.0, 1.0, 0.0), contact_velfactor: float = 0.02,
                         unit_scale: float = 1.0) -> MotionWindows:
    """Slice motions into canonicalised windows with foot contacts (official LaFAN1 pipeline).

    Contacts are computed on the raw (un-centred) window's FK positions with the official squared
    velocity threshold ``contact_velfactor`` (cm^2 / frame^2), positions converted to cm by ``unit_scale``
    (cm per file unit). All motions must share one frame rate (resample them first:
    :func:`inbetween_jax.data.resample.resample_motion`); windows and thresholds count frames.
    """
    if not motions:
        raise ValueError("no motions given")
    skel = motions[0].skeleton
    fps = motions[0].fps
    for m in motions[1:]:
        if abs(m.fps - fps) > 2e-3 * fps:
            raise ValueError(f"{m.source}: {m.fps:.3f} fps differs from {motions[0].source} ({fps:.3f} fps); "
                             "resample the motions to one rate first")
    quats, roots, contacts, names = [], [], [], []
    feet = list(skel.foot_joints())
    for m in motions:
        if not m.skeleton.same_topology(skel):
            raise ValueError(f"{m.source}: skeleton differs from {motions[0].source}")
        _, gp = forward_kinematics(m.local_quats, m.local_pos, skel.parents)
        c = foot_contacts(gp[:, feet], contact_velfactor, unit_scale)
        for s in window_starts(m.num_frames, window, offset):
            quats.append(m.local_quats[s:s + window])
            roots.append(m.root_pos[s:s + window])
            # official: contacts are re-derived per window, the last frame duplicating the previous one
            cw = c[s:s + window].copy()
            cw[-1] = cw[-2] if window > 1 else cw[-1]
            contacts.append(cw)
            names.append(f"{m.source.rsplit('/', 1)[-1].rsplit('.', 1)[0]}@{s}")
    if not quats:
        raise ValueError(f"no {window}-frame window fits in {len(motions)} motion(s) "
                         f"(longest has {max(m.num_frames for m in motions)} frames)")
    lq, root = canonicalize(np.stack(quats), np.stack(roots), skel, n_past, forward_axis)
    return MotionWindows(lq.astype(np.float32), root.astype(np.float32), np.stack(contacts).astype(np.float32),
                         skel, names, float(round(1.0 / motions[0].frame_time, 6)), float(unit_scale))
