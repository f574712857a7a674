"""A transition bank of training motion: nearest-neighbour in-betweens blended with the S-CVAE's samples.

Beyond the paper; inference only (the trained network is the same with or without), off unless a run's config
turns it on (``model.bank_k`` > 0, ``model.bank_weight``, ``model.bank_tau``).  The bank holds the training
clips' local rotations and root positions (``bank.npz`` in a run or shipped weights folder, written by
``inbetween build-bank``).

:func:`knn_transition` finds, for two keyframes ``length + 1`` frames apart, the ``k`` training transitions of
the same length whose two keyframes lie nearest to the query's: every joint's position at both keyframes, each
pair in the space of its start keyframe (root on the origin in the floor plane, facing +Z), so the match sees the
poses and where the target lies relative to the start. Each is warped onto the query's keyframes (Witkin &
Popovic 1995: per joint, the rotation offset at the two ends slerped over the transition; the root's position
offset lerped) and the ``k`` are averaged, uniformly (``tau`` 0) or with weights ``exp(-(d - d_1) / (tau d_1))``
of their squared match distance ``d`` (``d_1`` the nearest's). Transitions whose root turns further than half a
turn (:data:`MAX_TURN`) are left out: two keyframes cannot tell a spin from none. :func:`blend` mixes that with
the network's samples (``bank_weight``: 1 keeps the bank's transition only). Why: at the CPU budget the S-CVAE
stays at Slerp's level (docs/results/scvae.md), while warped real transitions carry what the two keyframes imply
about the motion between them.
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from inbetween_jax.errors import NPZ_READ_ERRORS, UserError
from inbetween_jax.geometry.kinematics import forward_kinematics, local_positions
from inbetween_jax.geometry.mirror import MIRROR_TAG, rest_side_axis
from inbetween_jax.geometry.quaternion import quat_from_axis_angle, quat_inv, quat_mul, quat_normalize, quat_rotate
from inbetween_jax.geometry.quaternion import quat_align, quat_fix_sign_np, quat_slerp
from inbetween_jax.models.scvae.timing import retimed

__all__ = ["BANK_FILE", "SWITCHES", "MIRROR_TAG", "TransitionBank", "keyframe_space", "knn_transition",
           "knn_base_path", "pad_base_path", "blend", "sample_blend", "bank_sample_blend",
           "sampled_mode", "sample_weight", "sample_timing_spread", "bank_enabled", "bank_searched", "bank_needed",
           "check_mirror"]

BANK_FILE = "bank.npz"
SWITCHES = ("model.bank_k", "model.bank_weight", "model.bank_tau", "model.bank_sample_weight",          # inference only
            "model.timing_spread", "model.timing_parts", "model.timing_spread_in_clip",
            "model.timing_spread_fallback")
CACHED_LENGTHS = 8        # transition lengths whose match features a bank keeps (about 30 MB each for CMU)
QUERY_CHUNK = 64          # queries warped at once (memory: chunk x k x frames x joints x 4)
MAX_TURN = np.pi          # bank transitions whose root turns further than this (radians) are not candidates


@dataclasses.dataclass
class TransitionBank:
    """Training clips for retrieval, concatenated: local_quats (F, J, 4) float32, root_pos (F, 3) float32,
    clip_starts (C + 1,) the first frame of each clip and F; names (C,); offsets (J, 3) and parents: the skeleton
    (FK of the match features); forward_axis (3,): the root's local facing axis; stride: frames between bank
    transitions.  Match features are cached per transition length (:meth:`index`)."""
    local_quats: np.ndarray
    root_pos: np.ndarray
    clip_starts: np.ndarray
    names: tuple
    offsets: np.ndarray
    parents: tuple
    forward_axis: np.ndarray
    stride: int = 2
    cache_lengths: int = CACHED_LENGTHS
    _cache: dict = dataclasses.field(default_factory=dict, repr=False, compare=False)
    _facing: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)

    @classmethod
    def from_motions(cls, motions, forward_axis, stride: int = 2, mirror: bool = False) -> "TransitionBank":
        """A bank of :class:`~inbetween_jax.data.Motion` s on one skeleton (and one frame rate); ``mirror``: each
        motion's left-right mirror image (:meth:`~inbetween_jax.data.Motion.mirrored`) too, named with
        :data:`MIRROR_TAG`.  Raises UserError (one line): no motions, or a mirror on a rig without one."""
        if not motions:
            raise UserError("transition bank: no training motions to build it from")
        skel = motions[0].skeleton
        names = [str(m.source).rsplit("/", 1)[-1] for m in motions]
        if mirror:                                  # one skeleton: checked once
            check_mirror(skel, forward_axis, motions[0].source)
            motions = list(motions) + [m.mirrored() for m in motions]
            names += [n + MIRROR_TAG for n in names]
        lens = [m.num_frames for m in motions]
        return cls(np.concatenate([m.local_quats for m in motions]).astype(np.float32),
                   np.concatenate([m.root_pos for m in motions]).astype(np.float32),
                   np.concatenate([[0], np.cumsum(lens)]).astype(np.int64), tuple(names),
                   np.asarray(skel.offsets, np.float64), tuple(int(p) for p in skel.parents),
                   np.asarray(forward_axis, np.float64), int(stride))

    @property
    def num_frames(self) -> int:
        return int(self.clip_starts[-1])

    @property
    def num_joints(self) -> int:
        return int(self.local_quats.shape[1])

    def save(self, path: str) -> None:
        """Write ``path`` (npz; rotations as float16) atomically."""
        tmp = path + ".tmp.npz"
        np.savez_compressed(tmp, local_quats=self.local_quats.astype(np.float16), root_pos=self.root_pos,
                            clip_starts=self.clip_starts, names=np.asarray(self.names), offsets=self.offsets,
                            parents=np.asarray(self.parents, np.int64), forward_axis=self.forward_axis,
                            stride=np.int64(self.stride))
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: str) -> "TransitionBank":
        """Read a bank written by :meth:`save`.  Raises UserError (one line) on a missing or malformed file."""
        try:
            with np.load(path, allow_pickle=False) as z:
                bank = cls(np.asarray(z["local_quats"], np.float32), np.asarray(z["root_pos"], np.float32),
                           np.asarray(z["clip_starts"], np.int64), tuple(str(n) for n in z["names"]),
                           np.asarray(z["offsets"], np.float64), tuple(int(p) for p in z["parents"]),
                           np.asarray(z["forward_axis"], np.float64), int(z["stride"]))
        except (*NPZ_READ_ERRORS, KeyError) as e:
            raise UserError(f"{path}: not a readable transition bank ({e})") from None
        f, j = bank.local_quats.shape[:2] if bank.local_quats.ndim == 3 else (-1, -1)
        if (bank.local_quats.ndim != 3 or bank.local_quats.shape[-1] != 4 or bank.root_pos.shape != (f, 3)
                or bank.offsets.shape != (j, 3) or len(bank.parents) != j or bank.clip_starts[-1] != f
                or not np.all(np.isfinite(bank.local_quats)) or bank.stride < 1):
            raise UserError(f"{path}: not a transition bank (expected rotations (F, J, 4), roots (F, 3) and a "
                            f"J-joint skeleton)")
        norm = np.linalg.norm(bank.local_quats, axis=-1, keepdims=True)
        if norm.size and norm.min() < 0.5:
            raise UserError(f"{path}: not a transition bank (rotations are not unit quaternions)")
        bank.local_quats = bank.local_quats / norm                      # float16 storage
        return bank

    def index(self, length: int):
        """``(frames, yaw, xz, feats)`` of every bank transition of ``length`` in-between frames (stride
        :attr:`stride`): its start keyframe's index (N,), facing (N,) and floor position (N, 2), and its match
        features (N, 2 J 3) float32; cached for the :attr:`cache_lengths` lengths used last."""
        if length in self._cache:
            self._cache[length] = self._cache.pop(length)              # most recently used last
            return self._cache[length]
        while len(self._cache) >= self.cache_lengths:
            self._cache.pop(next(iter(self._cache)))
        bounds = zip(self.clip_starts[:-1], self.clip_starts[1:])
        starts = [np.arange(a, b - length - 1, self.stride) for a, b in bounds]
        frames = np.concatenate(starts).astype(np.int64) if starts else np.zeros(0, np.int64)
        frames = frames[np.abs(self._turned(frames, length + 1)) <= MAX_TURN]
        if len(frames) == 0:
            raise UserError(f"transition bank: no clip holds a {length}-frame transition that turns less than half "
                            f"a turn")
        keys_q = np.stack([self.local_quats[frames], self.local_quats[frames + length + 1]], 1).astype(np.float64)
        keys_r = np.stack([self.root_pos[frames], self.root_pos[frames + length + 1]], 1).astype(np.float64)
        yaw, xz = keyframe_space(keys_q[:, 0, 0], keys_r[:, 0], self.forward_axis)
        feats = self._features(*_to_space(keys_q, keys_r, yaw, xz)).astype(np.float32)
        self._cache[length] = (frames, yaw, xz, feats)
        return self._cache[length]

    def clip_of(self, names) -> np.ndarray:
        """Bank clip index of each name (a file name, with or without its extension; -1 when not in the bank)."""
        where = {_stem(n): i for i, n in enumerate(self.names)}
        return np.asarray([where.get(_stem(n), -1) for n in names], np.int64)

    @property
    def source_clips(self) -> np.ndarray:
        """(C,) each clip's own index, or for a mirror image (:data:`MIRROR_TAG`) its original's: a query
        excluded from its own motion is excluded from that motion's mirror image too."""
        own = self.clip_of([n[:-len(MIRROR_TAG)] if n.endswith(MIRROR_TAG) else n for n in self.names])
        return np.where(own < 0, np.arange(len(self.names)), own)

    def _turned(self, frames, span: int):
        """Root facing change (radians, unwrapped: a full spin is 2 pi) from each of ``frames`` to ``span``
        frames later.  Two keyframes cannot tell a spin from standing still, so spins are left out."""
        if self._facing is None:
            yaw = keyframe_space(self.local_quats[:, 0].astype(np.float64), self.root_pos, self.forward_axis)[0]
            step = np.angle(np.exp(1j * np.diff(yaw)))                      # per frame, wrapped to (-pi, pi]
            self._facing = np.concatenate([[0.0], np.cumsum(step)])
        return self._facing[frames + span] - self._facing[frames]

    def _features(self, q, r):
        """q (N, 2, J, 4), r (N, 2, 3) keyframe pairs in their start's space -> (N, 2 J 3) joint positions."""
        _, gp = forward_kinematics(q, local_positions(r, self.offsets), self.parents)
        return gp.reshape(len(gp), -1)


def _stem(name) -> str:
    """A clip name without folders and extension (a mirror image's tag kept)."""
    n = str(name).rsplit("/", 1)[-1]
    tag = MIRROR_TAG if n.endswith(MIRROR_TAG) else ""
    return n[:len(n) - len(tag)].rsplit(".", 1)[0] + tag


def check_mirror(skel, forward_axis, source, what: str = "transition bank mirror") -> None:
    """UserError (one line, naming ``source``) when the rig ``skel`` has no mirror
    (:func:`~inbetween_jax.geometry.mirror.rest_side_axis`), or the root's facing axis lies across the mirror (the
    mirror image would face backwards)."""
    try:
        axis = rest_side_axis(skel.offsets, skel.mirror_map())
    except ValueError as e:
        raise UserError(f"{source}: {what}: {e}") from None
    fa = np.asarray(forward_axis, np.float64)
    if abs(fa[axis]) > 0.1 * np.linalg.norm(fa):
        raise UserError(f"{source}: {what}: the facing axis {fa.tolist()} is not "
                        f"perpendicular to the rig's left-right axis {'xyz'[axis]}")


def keyframe_space(q_root, root, forward_axis):
    """Facing (yaw about +Y, 0 = +Z) and floor position of frames: q_root (N, 4), root (N, 3) -> (N,), (N, 2)."""
    f = quat_rotate(q_root, np.broadcast_to(np.asarray(forward_axis, np.float64), q_root.shape[:-1] + (3,)))
    return np.arctan2(f[..., 0], f[..., 2]), np.asarray(root)[..., [0, 2]]


def _yaw_quat(yaw):
    up = np.zeros(np.shape(yaw) + (3,))
    up[..., 1] = 1.0
    return quat_from_axis_angle(up, yaw)


def _to_space(q, r, yaw, xz):
    """Frames q (N, T, J, 4), r (N, T, 3) into the space facing ``yaw`` (N,) at floor position ``xz`` (N, 2)."""
    inv = _yaw_quat(-yaw)[:, None]
    q = q.copy()
    q[:, :, 0] = quat_mul(np.broadcast_to(inv, q[:, :, 0].shape), q[:, :, 0])
    r = r - np.stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]], -1)[:, None]
    return q, quat_rotate(np.broadcast_to(inv, r.shape[:-1] + (4,)), r)


def _from_space(q, r, yaw, xz):
    """Inverse of :func:`_to_space`."""
    rot = _yaw_quat(yaw)[:, None]
    q = q.copy()
    q[:, :, 0] = quat_mul(np.broadcast_to(rot, q[:, :, 0].shape), q[:, :, 0])
    r = quat_rotate(np.broadcast_to(rot, r.shape[:-1] + (4,)), r)
    return q, r + np.stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]], -1)[:, None]


def _warped_mean(cand_q, cand_r, key_q, key_r, weights):
    """Warp candidates onto the keyframes and average them.

    cand_q (B, k, L + 2, J, 4), cand_r (B, k, L + 2, 3): the candidates' frames, keyframes included, in the
    query's space; key_q (B, 2, J, 4), key_r (B, 2, 3): the query's two keyframes; weights (B, k) summing to 1.
    Returns (B, L + 2, J, 4), (B, L + 2, 3): the warped mean, equal to the query's keyframes at both ends.
    """
    n = cand_q.shape[2]
    t = np.arange(n) / (n - 1)
    d0 = quat_mul(key_q[:, None, 0], quat_inv(cand_q[:, :, 0]))                   # (B, k, J, 4) offsets
    d1 = quat_align(quat_mul(key_q[:, None, 1], quat_inv(cand_q[:, :, -1])), d0)
    warp_q = quat_mul(quat_slerp(d0[:, :, None], d1[:, :, None], t[None, None, :, None]), cand_q)
    o0, o1 = key_r[:, None, 0] - cand_r[:, :, 0], key_r[:, None, 1] - cand_r[:, :, -1]   # (B, k, 3)
    warp_r = cand_r + o0[:, :, None] + t[None, None, :, None] * (o1 - o0)[:, :, None]
    warp_q = quat_align(warp_q, warp_q[:, :1])
    w = weights[:, :, None, None]
    return quat_normalize((warp_q * w[..., None]).sum(1)), (warp_r * w).sum(1)


def knn_transition(bank: TransitionBank, key_q, key_r, tgt_q, tgt_r, length: int, k: int, tau: float = 0.0,
                   exclude=None, each: bool = False):
    """The bank's in-between of ``length`` frames between keyframes ``key`` and ``tgt`` (``length + 1`` apart).

    key_q, tgt_q: (B, J, 4) local quaternions; key_r, tgt_r: (B, 3) root positions, any world space.
    Returns q (B, length, J, 4), r (B, length, 3) float64 in the same space (signs continuous from the start
    keyframe's), and the nearest match's distance (B,): root mean square over the joints of both keyframes, in
    the data's units.  exclude: (B,) a bank clip index per query (:meth:`TransitionBank.clip_of`; -1: none)
    whose transitions are not candidates for it (training: a window never retrieves its own motion).
    ``each``: the k nearest one by one, nearest first, each warped onto the keyframes (no mean): q (B, k, length,
    J, 4), r (B, k, length, 3) (``tau`` unused).
    """
    frames, yaw_b, xz_b, feats = bank.index(length)
    feats = feats.astype(np.float64)
    k = int(min(k, len(frames)))
    key_q2 = np.stack([key_q, tgt_q], 1).astype(np.float64)
    key_r2 = np.stack([key_r, tgt_r], 1).astype(np.float64)
    out_q, out_r, out_d = [], [], []
    f2 = np.sum(feats ** 2, 1)
    clips = (bank.source_clips[np.searchsorted(bank.clip_starts, frames, side="right") - 1]
             if exclude is not None else None)
    n = length + 2
    for lo in range(0, len(key_q2), QUERY_CHUNK):
        q2, r2 = key_q2[lo:lo + QUERY_CHUNK], key_r2[lo:lo + QUERY_CHUNK]
        yaw, xz = keyframe_space(q2[:, 0, 0], r2[:, 0], bank.forward_axis)
        sq, sr = _to_space(q2, r2, yaw, xz)
        g = bank._features(sq, sr)
        d2 = np.sum(g ** 2, 1)[:, None] - 2.0 * g @ feats.T + f2[None]
        if exclude is not None:
            d2[clips[None] == np.asarray(exclude)[lo:lo + QUERY_CHUNK, None]] = np.inf
        near = np.argpartition(d2, k - 1, axis=1)[:, :k] if k < d2.shape[1] else np.argsort(d2, 1)
        dk = np.take_along_axis(d2, near, 1)
        order = np.argsort(dk, 1)
        near, dk = np.take_along_axis(near, order, 1), np.maximum(np.take_along_axis(dk, order, 1), 0.0)
        if tau > 0:
            w = np.exp(-(dk - dk[:, :1]) / (tau * np.maximum(dk[:, :1], 1e-9)))
        else:
            w = np.ones_like(dk)
        w = w / w.sum(1, keepdims=True)
        b = len(q2)
        idx = frames[near][..., None] + np.arange(n)                                # (b, k, L + 2)
        cq, cr = _to_space(bank.local_quats[idx].reshape(b * k, n, -1, 4).astype(np.float64),
                           bank.root_pos[idx].reshape(b * k, n, 3).astype(np.float64), yaw_b[near].reshape(-1),
                           xz_b[near].reshape(-1, 2))
        if each:            # every candidate its own query: (b k) warped transitions
            rep = lambda a: np.repeat(a, k, 0)
            mq, mr = _warped_mean(cq[:, None], cr[:, None], rep(sq), rep(sr), np.ones((b * k, 1)))
            mq, mr = _from_space(mq, mr, rep(yaw), rep(xz))
            mq[:, 0] = quat_align(mq[:, 0], rep(q2[:, 0]))
        else:
            mq, mr = _warped_mean(cq.reshape(b, k, n, -1, 4), cr.reshape(b, k, n, 3), sq, sr, w)
            mq, mr = _from_space(mq, mr, yaw, xz)
            mq[:, 0] = quat_align(mq[:, 0], q2[:, 0])         # the start keyframe's sign, then continuous in time
        mq, mr = quat_fix_sign_np(mq, axis=1)[:, 1:-1], mr[:, 1:-1]
        out_q.append(mq.reshape((b, k) + mq.shape[1:]) if each else mq)
        out_r.append(mr.reshape((b, k) + mr.shape[1:]) if each else mr)
        out_d.append(np.sqrt(dk[:, 0] / (2 * bank.num_joints)))
    return np.concatenate(out_q), np.concatenate(out_r), np.concatenate(out_d)


def knn_base_path(bank: TransitionBank, start_q, start_r, tgt_q, tgt_r, length: int, max_length: int, k: int,
                  tau: float = 0.0, exclude=None):
    """The residual decoder's base (``model.bank_base``) at times 0..max_length: the start keyframe, the bank's
    in-between of :func:`knn_transition` (``length - 1`` frames), the target at ``length`` and held after it.
    start_q, tgt_q (B, J, 4); start_r, tgt_r (B, 3).  Returns q (B, T1, J, 4), r (B, T1, 3) float32, T1 =
    max_length + 1, signs continuous from the start keyframe's."""
    q, r, _ = knn_transition(bank, start_q, start_r, tgt_q, tgt_r, length - 1, k, tau, exclude)
    return pad_base_path(start_q, start_r, tgt_q, tgt_r, q, r, max_length)


def pad_base_path(start_q, start_r, tgt_q, tgt_r, q, r, max_length: int):
    """:func:`knn_base_path` from an in-between already found: q (B, L - 1, J, 4), r (B, L - 1, 3) between the
    keyframes, framed by the start keyframe and the target (held to time max_length)."""
    length = q.shape[1] + 1
    hold = max_length + 1 - length
    tq = quat_align(np.asarray(tgt_q, np.float64)[:, None], q[:, -1:])
    bq = np.concatenate([np.asarray(start_q, np.float64)[:, None], q, np.repeat(tq, hold, 1)], 1)
    br = np.concatenate([np.asarray(start_r, np.float64)[:, None], r,
                         np.repeat(np.asarray(tgt_r, np.float64)[:, None], hold, 1)], 1)
    return bq.astype(np.float32), br.astype(np.float32)


def blend(q, r, bank_q, bank_r, weight: float):
    """Mix samples q (S, B, L, J, 4), r (S, B, L, 3) with the bank's transition bank_q (B, L, J, 4),
    bank_r (B, L, 3): slerp / lerp by ``weight`` (0: the samples, 1: the bank's)."""
    q, r = np.asarray(q, np.float64), np.asarray(r, np.float64)
    return quat_slerp(q, quat_align(np.asarray(bank_q, np.float64)[None], q), weight), r + weight * (bank_r[None] - r)


def sample_blend(q, r, each_q, each_r, weight: float):
    """The sampled mode (``model.bank_sample_weight``): sample 0 of q (S, B, L, J, 4), r (S, B, L, 3) as it is,
    sample s >= 1 slerped / lerped by ``weight`` toward the bank's ``(s - 1) % k``-th nearest transition
    (``each_q`` (B, k, L, J, 4), ``each_r`` (B, k, L, 3), :func:`knn_transition` with ``each``), so the samples
    differ by captured motion.  Returns float64 arrays of q's and r's shapes."""
    q, r = np.array(q, np.float64), np.array(r, np.float64)
    k = each_q.shape[1]
    for s in range(1, q.shape[0]):
        j = (s - 1) % k
        bq, br = blend(q[s:s + 1], r[s:s + 1], each_q[:, j], each_r[:, j], weight)
        q[s], r[s] = bq[0], br[0]
    return q, r


def bank_sample_blend(bank: TransitionBank, key_q, key_r, tgt_q, tgt_r, q, r, weight: float, timing=0.0,
                      parts=None):
    """:func:`sample_blend` of samples q (S, B, L, J, 4), r (S, B, L, 3) of the in-betweens between keyframes
    ``key`` and ``tgt`` (key_q, tgt_q (B, J, 4); key_r, tgt_r (B, 3), the samples' space) with the bank's S - 1
    nearest transitions (:func:`knn_transition` with ``each``); then, with ``timing`` > 0 (a number or (B,), see
    :func:`sample_timing_spread`), each sample s >= 1 retimed (:func:`~.timing.retimed`; ``parts``: (J,) body part
    labels for part-wise timing, or None)."""
    each_q, each_r, _ = knn_transition(bank, key_q, key_r, tgt_q, tgt_r, q.shape[2], q.shape[0] - 1, each=True)
    q, r = sample_blend(q, r, each_q, each_r, weight)
    return retimed(key_q, key_r, tgt_q, tgt_r, q, r, timing, parts) if np.any(np.asarray(timing) > 0) else (q, r)


def sampled_mode(model_cfg, num_samples: int) -> bool:
    """The samples after the first are blended with one bank transition each (:func:`sample_blend`)."""
    return float(getattr(model_cfg, "bank_sample_weight", 0.0)) > 0 and num_samples > 1


def bank_enabled(model_cfg) -> bool:
    """The samples are blended with the bank's transition."""
    return int(getattr(model_cfg, "bank_k", 0)) > 0 and float(getattr(model_cfg, "bank_weight", 0.0)) > 0


def bank_searched(model_cfg) -> bool:
    """Every sample uses the bank's k-nearest mean transition: blended in (:func:`bank_enabled`) or as the
    residual base (``bank_base``)."""
    return bank_enabled(model_cfg) or bool(getattr(model_cfg, "bank_base", False))


def bank_needed(model_cfg) -> bool:
    """The model needs a bank: for the blend (:func:`bank_enabled`), as its residual base (``bank_base``) or for
    the sampled mode (``bank_sample_weight``)."""
    return bank_searched(model_cfg) or float(getattr(model_cfg, "bank_sample_weight", 0.0)) > 0


def sample_weight(cfg, gate_weight=None):
    """The sampled mode's blend weight: ``cfg.bank_sample_weight``, times the gate's weight (a number or (B,)
    array) with ``cfg.bank_sample_gated``, so samples leave the fill toward captured motion only where the gate
    says the keyframes are inside the training motion.  Returns a number or a (B, 1, 1) array."""
    if not cfg.bank_sample_gated or gate_weight is None:
        return cfg.bank_sample_weight
    w = cfg.bank_sample_weight * np.asarray(gate_weight, np.float64)
    return float(w) if w.ndim == 0 else w[:, None, None]


def sample_timing_spread(cfg, gate_weight=None):
    """The sampled mode's timing spread between two keyframes alone: ``cfg.timing_spread``; with
    ``cfg.timing_spread_fallback`` > 0 and the gate's weight (a number or (B,) array), lerped from the fallback
    spread (weight 0: the fill is Slerp, whose timing the keyframes pin least) to ``timing_spread`` (weight 1: the
    network's, which carries timing of its own).  Returns a number or a (B,) array."""
    fallback = float(getattr(cfg, "timing_spread_fallback", 0.0))
    if fallback <= 0 or gate_weight is None:
        return cfg.timing_spread
    w = np.clip(np.asarray(gate_weight, np.float64), 0.0, 1.0)
    out = fallback + (cfg.timing_spread - fallback) * w
    return float(out) if out.ndim == 0 else out
