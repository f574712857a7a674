"""Users' motions on another rig or frame rate than a checkpoint's: joints matched by name, resampling.

A user's skeleton may hold more joints than the checkpoint's (a 43-joint CMU file with fingers and eyes for a
checkpoint trained on the 21-joint body): :func:`match_joints` finds every checkpoint joint by name,
:func:`restrict` gives the motion on the checkpoint's joints (a joint whose parent chain in the user's rig passes
through unmatched joints gets their composed rotation, so world orientations are kept) and :func:`expand` puts a
generated motion back on the user's full skeleton (matched joints take the generated rotations with that
composition undone; the extra joints keep the user's values on known frames and are slerped across the
generated ones).  :func:`prepare` does all of it for one input file, resampling it to the checkpoint's rate and
converting it to the checkpoint's length unit (:meth:`Prepared.to_file_unit` converts a generated motion back).
Pure NumPy; every problem is a one-line :class:`~inbetween_jax.errors.UserError` naming the file.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from inbetween_jax.data.resample import fill_unknown, known_frames
from inbetween_jax.errors import UserError

__all__ = ["JointMatch", "match_joints", "restrict", "expand", "Prepared", "prepare", "to_frame"]

MAX_LISTED = 8
UNIT_TOLERANCE = 0.02     # a file whose body is within 2 % of the checkpoint's size is taken in the same unit


@dataclasses.dataclass(frozen=True)
class JointMatch:
    """Where the checkpoint's joints are in a user's rig.

    user: (J_ckpt,) the user-rig index of every checkpoint joint.
    chains: per checkpoint joint, the user-rig indices of the unmatched joints between it and its checkpoint
        parent, outermost first (empty where the parent is the same).
    extra: user-rig indices of the joints the checkpoint does not have.
    """
    user: tuple
    chains: tuple
    extra: tuple

    @property
    def identity(self) -> bool:
        return not self.extra and self.user == tuple(range(len(self.user)))


def _listing(names) -> str:
    names = list(names)
    shown = ", ".join(names[:MAX_LISTED])
    return shown + (", ..." if len(names) > MAX_LISTED else "")


def match_joints(user_skel, ckpt_skel, path: str = "") -> JointMatch:
    """Match every joint of ``ckpt_skel`` to the joint of the same name in ``user_skel``.

    Raises:
        UserError: joints missing (listed, at most eight), the roots differ, or a joint hangs below another
            parent than in the checkpoint's skeleton.
    """
    where = {n: i for i, n in enumerate(user_skel.names)}
    missing = [n for n in ckpt_skel.names if n not in where]
    if missing:
        raise UserError(f"{path}: skeleton lacks {len(missing)} of the checkpoint's {ckpt_skel.num_joints} joints: "
                        f"{_listing(missing)}")
    user = tuple(where[n] for n in ckpt_skel.names)
    if user[0] != 0:
        raise UserError(f"{path}: root joint is {user_skel.names[0]!r} but the checkpoint's root is "
                        f"{ckpt_skel.names[0]!r}")
    matched = set(user)
    chains = [()]
    for j in range(1, ckpt_skel.num_joints):
        target, chain, k = user[ckpt_skel.parents[j]], [], user_skel.parents[user[j]]
        while k != target:
            if k < 0 or k in matched:
                raise UserError(f"{path}: joint {ckpt_skel.names[j]!r} is not below "
                                f"{ckpt_skel.names[ckpt_skel.parents[j]]!r} as in the checkpoint's skeleton")
            chain.append(k)
            k = user_skel.parents[k]
        chains.append(tuple(reversed(chain)))
    extra = tuple(i for i in range(user_skel.num_joints) if i not in matched)
    return JointMatch(user, tuple(chains), extra)


def _chain_quat(q, chain):
    """Product of the local rotations (T, J, 4) of ``chain`` (outermost first): (T, 4), or None if empty."""
    from inbetween_jax.geometry.quaternion import quat_mul
    out = None
    for k in chain:
        out = q[:, k] if out is None else quat_mul(out, q[:, k])
    return out


def restrict(motion, match: JointMatch, ckpt_skel):
    """``motion`` (T frames on the user's rig) on the checkpoint's joints: a Motion (T, J_ckpt) whose
    skeleton has the checkpoint's names and parents and the user's offsets and channels (offsets of a joint
    with skipped intermediates are summed along the chain)."""
    from inbetween_jax.data.bvh import Motion
    from inbetween_jax.data.skeleton import Skeleton
    from inbetween_jax.geometry.quaternion import quat_mul
    q, p = np.asarray(motion.local_quats, np.float64), np.asarray(motion.local_pos, np.float64)
    us = motion.skeleton
    quats, pos, offsets = [], [], []
    for u, chain in zip(match.user, match.chains):
        cq = _chain_quat(q, chain)
        quats.append(q[:, u] if cq is None else quat_mul(cq, q[:, u]))
        pos.append(p[:, u] + sum((p[:, k] for k in chain), np.zeros(3)))
        offsets.append(us.offsets[u] + sum((us.offsets[k] for k in chain), np.zeros(3)))
    skel = Skeleton(tuple(ckpt_skel.names), tuple(ckpt_skel.parents), np.stack(offsets),
                    tuple(us.channels[u] for u in match.user))
    return Motion(skel, np.stack(quats, axis=1), np.stack(pos, axis=1), motion.frame_time, motion.source)


def expand(generated, user, match: JointMatch, known=None):
    """A generated motion on the checkpoint's joints back on the user's full skeleton.

    generated: Motion (T, J_ckpt); user: Motion (T, J_user) on the user's rig whose ``known`` frames hold the
    user's values (the others are ignored); known: (T,) bool, default only the first and last frame.
    Returns a Motion (T, J_user) with ``user``'s skeleton and frame time: known frames exactly the user's;
    elsewhere the extra joints slerped (positions lerped) between known frames, the matched joints the
    generated rotations with the extra joints' composition undone, the root trajectory the generated one.
    """
    from inbetween_jax.geometry.quaternion import quat_fix_sign_np, quat_inv, quat_mul
    known = known_frames(generated, user, known, "expand")
    q = fill_unknown(user.local_quats, known, rotations=True)
    p = fill_unknown(user.local_pos, known, rotations=False)
    miss = ~known
    gq = np.asarray(generated.local_quats, np.float64)
    for j, (u, chain) in enumerate(zip(match.user, match.chains)):
        cq = _chain_quat(q, chain)
        qu = gq[:, j] if cq is None else quat_mul(quat_inv(cq), gq[:, j])
        q[miss, u] = qu[miss]
    p[miss, 0] = np.asarray(generated.local_pos, np.float64)[miss, 0]
    q[miss] = (q / np.linalg.norm(q, axis=-1, keepdims=True))[miss]
    q[miss] = quat_fix_sign_np(q, axis=0)[miss]
    return dataclasses.replace(user, local_quats=q, local_pos=p, frame_time=generated.frame_time)


@dataclasses.dataclass
class Prepared:
    """One input file ready for a checkpoint: ``full`` (the file at the checkpoint's rate, user's rig),
    ``motion`` (``full`` on the checkpoint's joints and in its length unit; ``full`` itself for an exact match in
    the same unit), ``match`` (None for an exact match or a transfer), ``ratio`` (checkpoint fps / file fps; 1.0
    when not resampled), ``note``, ``factor`` (checkpoint units per file unit; 1.0 when not converted),
    ``transfer`` (the :data:`~inbetween_jax.data.rig_transfer.RIGS` profile when another rig was put on the
    checkpoint's body by bone directions, else None)."""
    path: str
    full: object
    motion: object
    match: JointMatch | None
    ratio: float
    note: str | None
    factor: float = 1.0
    transfer: str | None = None

    def to_file_unit(self, motion):
        """A motion in the checkpoint's unit (``motion``'s, or one generated from it) -> the file's unit."""
        return motion if self.factor == 1.0 else motion.scaled(1.0 / self.factor)

    @property
    def on_other_rig(self) -> bool:
        """Whether generated motions need the file's rig put back (:meth:`on_user_rig`)."""
        return self.match is not None or self.transfer is not None

    def end_keys(self, start: int, end, end_frame: int, frames: int):
        """The keyframes a generated transition is put back between: a Motion on the file's rig of ``frames``
        frames, frame ``start`` of :attr:`full` throughout but the last, which is frame ``end_frame`` of
        ``end.full`` (``end``: this Prepared or the end keyframe's file's).  The ``user`` of :meth:`on_user_rig`
        with its default ``known`` (the first and the last frame)."""
        idx = np.full(frames, start)
        keys = dataclasses.replace(self.full, local_quats=self.full.local_quats[idx],
                                   local_pos=self.full.local_pos[idx])
        keys.local_quats[-1], keys.local_pos[-1] = end.full.local_quats[end_frame], end.full.local_pos[end_frame]
        return keys

    def on_user_rig(self, generated, user=None, known=None):
        """A motion generated on the checkpoint's joints and unit -> the file's rig and unit.  ``user``: a Motion
        on the file's rig with the same frame count whose ``known`` frames (default the first and the last) are
        kept exactly (default :attr:`full`); :func:`expand` for a larger rig, :func:`~inbetween_jax.data.
        rig_transfer.transfer_back` for a transferred one."""
        motion = self.to_file_unit(generated)
        user = self.full if user is None else user
        if self.match is not None:
            return expand(motion, user, self.match, known)
        if self.transfer is not None:
            from inbetween_jax.data.rig_transfer import transfer_back
            return transfer_back(motion, user, known)
        return motion


def to_frame(prep: Prepared, frame: int, side: str | None = None) -> int:
    """A frame number of the file -> a frame of the resampled motion: the nearest one, or with ``side="start"``
    the last one at or before it and with ``side="end"`` the first one at or after it.  A resampled frame between
    two file frames is interpolated from both, so a keyframe that starts (ends) a fill is taken from the frames up
    to (from) its own and never from the frames the fill replaces."""
    u = frame * prep.ratio
    if side not in (None, "start", "end"):
        raise ValueError(f"side must be None, 'start' or 'end', not {side!r}")
    from inbetween_jax.data.resample import FRAME_TOL
    k = np.floor(u + FRAME_TOL) if side == "start" else np.ceil(u - FRAME_TOL) if side == "end" else round(u)
    return min(max(int(k), 0), prep.full.num_frames - 1)


def prepare(motion, path: str, ckpt_skel, fps=None) -> Prepared:
    """Resample ``motion`` to ``fps`` (None: keep), match it to ``ckpt_skel`` (None: take as it is) and convert it
    to ``ckpt_skel``'s length unit (:func:`~inbetween_jax.data.features.unit_factor`: detected from the leg
    length, e.g. the 1/128-scaled CMU salsa files or CMU's 0.0564 m unit; :attr:`Prepared.factor`).  The CAE's
    features, the S-CVAE's root velocities and every gate's speed are in the training data's unit: a file in
    metres would otherwise read as a body standing still.

    An exact match at the same rate returns ``motion`` untouched (``note`` None).  A rig that is not larger
    than the checkpoint's and does not match is refused with :func:`~inbetween_jax.data.user_input.check_skeleton`'s
    line (first differing joint); a larger one lacking joints with :func:`match_joints`'s (the missing joints).
    """
    from inbetween_jax.data.resample import nominal_fps, resample_motion
    parts, ratio, full, transfer = [], 1.0, motion, None
    if fps is not None:
        src = nominal_fps(motion.frame_time)
        full = resample_motion(motion, float(fps))
        if full is not motion:
            ratio = 1.0 / (full.frame_time * src)             # the rate resample_motion produced (snapped)
            parts.append(f"{src:g} fps resampled to the checkpoint's {float(fps):g} fps")
    match, out = None, full
    if ckpt_skel is not None and not full.skeleton.same_topology(ckpt_skel):
        from inbetween_jax.data.rig_transfer import rig_label, rig_of, takes_rig_transfer, transfer_rig
        try:
            match = match_joints(full.skeleton, ckpt_skel, path)
        except UserError:
            found = rig_of(full.skeleton)
            transfer = found[0] if found else None
            if transfer and takes_rig_transfer(ckpt_skel):
                # a known rig (CMU's 31-joint one, LaFAN1 / Mixamo names): put on the checkpoint's body
                out = transfer_rig(full, ckpt_skel, drop_tpose=False)
                match = None
                how = " (as its training captures were)" if transfer in ("mb31", "cmu-asf") else ""
                parts.append(f"the {rig_label(transfer)} put on the checkpoint's body by bone directions{how}, "
                             "the output back on the file's rig")
            else:
                if full.skeleton.num_joints <= ckpt_skel.num_joints:     # not a larger rig: say how it differs
                    from inbetween_jax.data.user_input import check_skeleton
                    check_skeleton(full.skeleton, path, ckpt_skel)
                raise
        if match is not None and match.identity:
            match = None
        elif match is not None:
            out = restrict(full, match, ckpt_skel)
            n = len(match.extra)
            parts.append(f"{n} extra joint{'s' if n != 1 else ''} follow{'s' if n == 1 else ''} by interpolation")
    factor = 1.0
    if ckpt_skel is not None:
        from inbetween_jax.data.features import unit_factor
        factor = float(unit_factor(out.skeleton, ckpt_skel))
        if abs(factor - 1.0) > UNIT_TOLERANCE:
            out = out.scaled(factor)
            parts.append(f"positions scaled by {factor:.4g} to the checkpoint's unit (and back on output)")
        else:
            factor = 1.0
    note = f"{path}: {'; '.join(parts)}" if parts else None
    return Prepared(path, full, out, match, ratio, note, factor, transfer)
