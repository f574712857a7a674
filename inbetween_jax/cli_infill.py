"""Model side of the ``inbetween`` command: input checks, checkpoint inspection and the three in-betweening
routines on users' own BVH files.

Every problem a user can cause raises :class:`~inbetween_jax.cli.UserError` (inputs given on the command line) or
``ValueError`` (the Python API) with a one-line message naming the file or array and the problem.  Nothing here
writes files; :mod:`inbetween_jax.cli` does.  (S-CVAE: :mod:`inbetween_jax.models.scvae.infer`.)

Canonical spaces.  Interaction inputs go to each character's keyframe space exactly as
:func:`inbetween_jax.models.interaction_data.keyframe_sample` does for training samples.
"""
from __future__ import annotations

import json
import os

import jax
import numpy as np

from inbetween_jax.cli import UserError
from inbetween_jax.data import BVHError, read_bvh
from inbetween_jax.geometry import quat_fix_sign_np, quat_inv, quat_mul


# ----------------------------------------------------------------------------- inputs
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
    """read_bvh with every failure turned into a one-line UserError naming the file."""
    try:
        return read_bvh(path)
    except BVHError as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"{path}: cannot read ({e.strerror or e})") from None


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
    if not skel.same_topology(ref):
        check_skeleton(skel, path, ref, what=ref_path)


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


def training_skeleton(source):
    """The skeleton of a run's training data (first BVH of its folder), or None when it is not available."""
    from inbetween_jax.data.datasets import EMBEDDED_DIR, resolve_source
    src = resolve_source(source)
    folder = EMBEDDED_DIR if src == "embedded" else src
    if not os.path.isdir(folder):
        return None
    files = sorted(f for f in os.listdir(folder) if f.lower().endswith(".bvh"))
    try:
        return read_bvh(os.path.join(folder, files[0])).skeleton if files else None
    except (BVHError, OSError):
        return None


def checkpoint_step(ckpt_dir: str, sub: str = "checkpoints") -> tuple:
    """``(checkpoint folder, latest step)`` of a run folder (or of its ``checkpoints`` folder itself)."""
    from inbetween_jax.train import Checkpointer
    if not os.path.exists(ckpt_dir):
        raise UserError(f"checkpoint folder {ckpt_dir!r} does not exist")
    if not os.path.isdir(ckpt_dir):
        raise UserError(f"{ckpt_dir}: not a folder (--ckpt takes a training run folder)")
    folder = os.path.join(ckpt_dir, sub) if os.path.isdir(os.path.join(ckpt_dir, sub)) else ckpt_dir
    ck = Checkpointer(folder)
    try:
        step = ck.latest_step()
    finally:
        ck.close()
    if step is None:
        raise UserError(f"{ckpt_dir}: no checkpoint found (expected {sub}/<step>/ written by training)")
    return folder, int(step)


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


# ----------------------------------------------------------------------------- CAE
def parse_gaps(text: str, num_frames=None, path: str = "") -> list:
    """``"100:160,300:420"`` -> ``[(100, 160), (300, 420)]`` (stop exclusive), checked against the clip."""
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
        mask = np.zeros(num_frames, bool)
        for a, b in gaps:
            mask[a:b] = True
        if mask.all():
            raise UserError(f"--gaps {text!r}: the gaps cover all {num_frames} frames of {path}; nothing is left "
                            "to fill from")
    return sorted(gaps)


# ----------------------------------------------------------------------------- interaction
def interaction_checkpoint(ckpt_dir: str) -> dict:
    """Config and metadata of an interaction run folder without loading its weights."""
    from inbetween_jax.configs.interaction import get_config
    from inbetween_jax.train import apply_overrides
    _, step = checkpoint_step(ckpt_dir)
    meta = read_json(os.path.join(ckpt_dir, "interaction_meta.json"), "not an interaction run folder")
    try:
        cfg = apply_overrides(get_config(meta["variant"]), meta["overrides"])
        num_joints, fa = int(meta["num_joints"]), np.asarray(meta["forward_axis"], np.float64)
    except (KeyError, TypeError, ValueError) as e:
        raise UserError(f"{ckpt_dir}: interaction_meta.json is incomplete ({e})") from None
    return {"cfg": cfg, "step": step, "meta": meta, "num_joints": num_joints, "forward_axis": fa,
            "skeleton": training_skeleton(meta.get("source"))}


def interaction_infill(run_dir: str, info: dict, context, keyframes, frames: int, num_samples: int,
                       seed: int = 0) -> np.ndarray:
    """Roll the interaction network out for ``frames`` frames after two characters' context windows.

    context: (2, n_input, J, 9) world features (positions + forward/up of global rotations) of the frames
    up to the start frame; keyframes: (2, J, 9) world features of the keyposes.  The network has no
    time-to-arrival input: it is rolled out for exactly ceil(frames / n_pred) steps (no early stop) and the
    first ``frames`` frames are kept.  Returns (S, 2, frames, J, 9) world features.
    """
    from inbetween_jax.models.interaction import sample_rollouts
    from inbetween_jax.models.interaction_data import (apply_space, relative_space, root_space, scale_positions,
                                                       to_space)
    from inbetween_jax.models.interaction_eval import restore_run
    cfg, fa = info["cfg"], info["forward_axis"]
    R, t = root_space(keyframes[:, 0], fa)                                      # (2, 3, 3), (2, 3)
    rel_R, rel_t = relative_space(R, t, R[::-1], t[::-1])
    b = {"x": to_space(context, R[:, None], t[:, None])[None], "keypose": to_space(keyframes, R, t)[None],
         "rel_R": rel_R[None], "rel_t": rel_t[None], "world_R": R[None], "world_t": t[None]}
    b = {k: v.astype(np.float32) for k, v in scale_positions(b, cfg.data.pos_scale).items()}
    _, nets, params, _ = restore_run(run_dir, info["step"])
    steps = -(-frames // cfg.data.n_pred)
    fn = jax.jit(lambda p, w, kp, rr, rt, k: sample_rollouts(nets, p, w, kp, rr, rt, k, cfg, fa.astype(np.float32),
                                                            steps, num_samples, threshold=-1.0)[0])
    out = np.asarray(fn(params, b["x"], b["keypose"], b["rel_R"], b["rel_t"], jax.random.key(seed)),
                     np.float64)[:, 0, :, :frames]                               # (S, 2, frames, J, 9)
    out[..., :3] /= cfg.data.pos_scale
    return apply_space(out, R[None, :, None], t[None, :, None])


def features_to_motion(feats, motion, start: int, key_motion, key_frame: int):
    """A character's generated world features (T, J, 9) -> a Motion on ``motion``'s skeleton holding
    [frame ``start`` of ``motion``, the T generated frames, frame ``key_frame`` of ``key_motion``].

    Rotations: the predicted global rotations (forward / up) made local, then every bone swung onto the
    predicted position of its main child with :func:`inbetween_jax.models.cae_infer.fit_rotations`
    (swing-only; twist from the predicted rotations; bone lengths are the skeleton's, so the written
    positions differ from the network's by its bone-length error).
    """
    import dataclasses
    from inbetween_jax.geometry import quat_from_forward_up, quat_normalize
    from inbetween_jax.geometry.fit import fit_rotations
    skel = motion.skeleton
    gq = quat_normalize(quat_from_forward_up(np.asarray(feats[..., 3:], np.float64)))
    par = np.asarray(skel.parents[1:])
    lq = np.concatenate([gq[:, :1], quat_mul(quat_inv(gq[:, par]), gq[:, 1:])], axis=1)
    lp = np.broadcast_to(motion.local_pos[start], lq.shape[:-1] + (3,)).copy()
    lq, lp = fit_rotations(feats[..., :3], lq, lp, skel.parents, np.ones(len(lq), bool))
    q = np.concatenate([motion.local_quats[start][None], lq, key_motion.local_quats[key_frame][None]])
    p = np.concatenate([motion.local_pos[start][None], lp, key_motion.local_pos[key_frame][None]])
    return dataclasses.replace(motion, local_quats=quat_fix_sign_np(quat_normalize(q)), local_pos=p)
