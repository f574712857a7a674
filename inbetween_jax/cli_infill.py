"""Model side of the ``inbetween`` command: input checks, checkpoint inspection and the three in-betweening
routines on users' own BVH files.

Every problem a user can cause raises :class:`~inbetween_jax.cli.UserError` (inputs given on the command line) or
``ValueError`` (the Python API, e.g. :func:`scvae_infill` given non-unit quaternions) with a one-line message
naming the file or array and the problem.  Nothing here writes files; :mod:`inbetween_jax.cli` does.

Canonical spaces.  S-CVAE keyframes are put in the space of the training windows with
:func:`inbetween_jax.data.windows.canonicalize` (centred in XZ on the mean root of the two keyframes -- the
training windows use the mean over the window, which the network never sees: it is only fed velocities and
offsets between frames -- and turned so that the start keyframe faces +X), and the samples are mapped back
with the inverse rigid motion.  Interaction inputs go to each character's keyframe space exactly as
:func:`inbetween_jax.models.interaction.features.keyframe_sample` does for training samples.
"""
from __future__ import annotations

import functools
import json
import os

import jax
import numpy as np

from inbetween_jax.cli import UserError
from inbetween_jax.data import BVHError, read_bvh
from inbetween_jax.data.features import foot_contacts
from inbetween_jax.geometry import forward_kinematics, quat_fix_sign_np, quat_inv, quat_mul, quat_rotate

SCVAE_MIN_FRAMES = 3          # L = frames + 1 >= 4 frames between keyframes (scvae.rollout)


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


def is_lafan1_skeleton(skel) -> bool:
    return skel.names[0] == "Hips" and "LeftToe" in skel.names


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


# ----------------------------------------------------------------------------- S-CVAE
def scvae_checkpoint(ckpt_dir: str) -> dict:
    """Config and metadata of an S-CVAE run folder without loading its weights."""
    from inbetween_jax.configs.scvae import config_from_dict
    from inbetween_jax.data import datasets, lafan1
    from inbetween_jax.train import Checkpointer
    folder, step = checkpoint_step(ckpt_dir)
    run_dir = os.path.dirname(folder) if os.path.basename(os.path.normpath(folder)) == "checkpoints" else ckpt_dir
    meta = {}
    if os.path.exists(os.path.join(run_dir, "run.json")):
        meta = read_json(os.path.join(run_dir, "run.json"), "S-CVAE run metadata")
    ck = Checkpointer(folder)
    try:
        extra = ck.restore_extra(step)
    finally:
        ck.close()
    if "config" not in extra or "model" not in extra["config"]:
        raise UserError(f"{ckpt_dir}: checkpoint {step} holds no S-CVAE config (is this an S-CVAE run folder?)")
    try:
        cfg = config_from_dict(extra["config"])
    except TypeError as e:
        raise UserError(f"{ckpt_dir}: checkpoint {step} holds no S-CVAE config ({e})") from None
    source = meta.get("source")
    lafan = bool(source) and datasets.is_lafan1(source)
    return {"cfg": cfg, "step": step, "folder": folder, "num_joints": meta.get("num_joints"), "source": source,
            "skeleton": training_skeleton(source) if source else None, "lafan1": lafan,
            "velfactor": lafan1.CONTACT_VELFACTOR if lafan else datasets.GENERIC_CONTACT_VELFACTOR}


def scvae_frame_range(cfg) -> tuple:
    """Transition lengths (generated frames between the keyframes) the S-CVAE was trained for."""
    return SCVAE_MIN_FRAMES, int(cfg.train.trans_max)


def scvae_restore(info: dict, num_joints: int):
    """Restore the train state (params, stats, ...) of :func:`scvae_checkpoint`'s run."""
    from inbetween_jax.models.scvae_train import make_init_fn
    from inbetween_jax.train import Checkpointer
    shapes = {"v_std": np.zeros(3, np.float32), "off_std": np.zeros(3, np.float32), "pos_unit": np.float32(0),
              "offsets": np.zeros((num_joints, 3), np.float32)}
    ck = Checkpointer(info["folder"])
    try:
        return ck.restore(info["step"], jax.eval_shape(make_init_fn(info["cfg"], shapes, num_joints),
                                                       jax.random.key(0)))
    except (ValueError, KeyError, TypeError) as e:
        raise UserError(f"{info['folder']}: checkpoint {info['step']} does not fit a {num_joints}-joint "
                        f"S-CVAE ({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
    finally:
        ck.close()


def keyframe_contacts(motion, frame: int, velfactor: float) -> np.ndarray:
    """(4,) foot contacts of one frame, from its displacement to the next frame (previous for the last)."""
    n = motion.num_frames
    if n < 2:
        return np.zeros(4, np.float32)
    a, b = (frame, frame + 1) if frame + 1 < n else (frame - 1, frame)
    _, gp = forward_kinematics(motion.local_quats[[a, b]], motion.local_pos[[a, b]], motion.skeleton.parents)
    return foot_contacts(gp[:, list(motion.skeleton.foot_joints())], velfactor)[0]


@functools.partial(jax.jit, static_argnames=("cfg", "max_length"))
def _scvae_sample(params, stats, start, target, keys, cfg, max_length):
    from inbetween_jax.models import scvae
    out = scvae.sample(params, cfg, stats, start, target, max_length, keys, max_length)["out"]
    return out["q"][:, 0], out["r"][:, 0]


def scvae_infill(cfg, state, skeleton, start: dict, end: dict, frames: int, num_samples: int, seed: int = 0,
                 forward_axis=None) -> dict:
    """Sample ``num_samples`` transitions of ``frames`` frames between two world-space keyframes.

    start / end: dicts with ``q`` (J, 4) unit local quaternions, ``r`` (3,) root position, ``c`` (4,) foot
    contacts.  skeleton: the keyframes' skeleton (its offsets give the FK of the canonicalisation).
    forward_axis: the root's local facing axis (default: inferred from ``skeleton``).
    Returns ``q`` (S, frames + 2, J, 4) and ``r`` (S, frames + 2, 3) float64 in the keyframes' world space;
    frame 0 is ``start`` and frame ``frames + 1`` is ``end``, both exactly as given.
    """
    import jax.numpy as jnp
    from inbetween_jax.data.windows import canonicalize
    lo, hi = scvae_frame_range(cfg)
    if not lo <= frames <= hi:
        raise ValueError(f"frames={frames}: this S-CVAE generates {lo}..{hi} frames between keyframes")
    if num_samples < 1:
        raise ValueError(f"num_samples={num_samples}: need at least one sample")
    qs = check_unit_quats(start["q"], "start keyframe q")
    qe = check_unit_quats(end["q"], "end keyframe q")
    for name, key in (("start", start), ("end", end)):
        r = np.asarray(key["r"], np.float64)
        if r.shape != (3,) or not np.all(np.isfinite(r)):
            raise ValueError(f"{name} keyframe r: expected 3 finite numbers, got {r!r}")
    fa = np.asarray(skeleton.forward_axis() if forward_axis is None else forward_axis, np.float64)
    roots = np.stack([start["r"], end["r"]]).astype(np.float64)
    cq, cr = canonicalize(np.stack([qs, qe])[None], roots[None], skeleton, 1, fa)      # (1, 2, J, 4), (1, 2, 3)
    yaw = quat_mul(qs[0], quat_inv(cq[0, 0, 0]))                                      # canonical -> world
    shift = np.array([roots[:, 0].mean(), 0.0, roots[:, 2].mean()])
    frame = lambda i, c: {"q": jnp.asarray(cq[:, i], jnp.float32), "r": jnp.asarray(cr[:, i], jnp.float32),  # noqa
                          "c": jnp.asarray(np.asarray(c, np.float32)[None])}
    keys = jax.random.split(jax.random.key(seed), num_samples)
    q, r = jax.device_get(_scvae_sample(state["params"], state["stats"], frame(0, start["c"]), frame(1, end["c"]),
                                        keys, cfg.model, frames + 1))
    q, r = np.asarray(q, np.float64)[:, :frames + 2], np.asarray(r, np.float64)[:, :frames + 2]
    q[:, :, 0] = quat_mul(np.broadcast_to(yaw, q[:, :, 0].shape), q[:, :, 0])
    r = quat_rotate(np.broadcast_to(yaw, r.shape[:-1] + (4,)), r) + shift
    q[:, 0], r[:, 0], q[:, -1], r[:, -1] = qs, roots[0], qe, roots[1]                 # exact keyframes
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return {"q": quat_fix_sign_np(q, axis=1), "r": r}


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
