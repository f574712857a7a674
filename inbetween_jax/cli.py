"""``inbetween``: in-betweening of users' own BVH files with a trained checkpoint.

Examples::

    inbetween infill --model scvae --ckpt runs/scvae --start a.bvh:0 --end b.bvh:120 --frames 30 --samples 10 --out out/
    inbetween infill --model cae --ckpt runs/cae/cae --bvh in.bvh --gaps 100:160,300:420 --out out/
    inbetween infill --model interaction --ckpt runs/interaction --a a.bvh:40 --b b.bvh:40 \\
        --key-a a.bvh:90 --key-b b.bvh:90 --frames 50 --samples 3 --out out/

Outputs (BVH on the skeleton of the input file, same joint names, offsets and channel layout):

* ``scvae``: ``sample_00.bvh`` ... -- frames+2 frames each: the start keyframe, ``--frames`` generated frames
  and the end keyframe (``:frame`` defaults to frame 0 of ``--start`` and the last frame of ``--end``).
* ``cae``: ``<stem>_filled.bvh`` (rotations refitted on the gap frames, swing-only) and ``<stem>_filled.npy``
  (T, J, 3) predicted global joint positions.
* ``interaction``: ``sample_00_A.bvh`` / ``sample_00_B.bvh`` ... -- frames+2 frames each: the start frame,
  ``--frames`` generated frames and the keyframe.  The start frame (default: the file's last frame) ends the
  context window of the model's ``n_input`` frames; the network predicts joint positions and global
  rotations in keyframe space, turned into BVH rotations by a swing-only fit (twist from the predicted
  rotations; see :func:`inbetween_jax.cli_infill.features_to_motion`).

``--preview`` adds, per sample, a contact sheet ``<sample>_sheet.png`` (keyframes / known frames black,
generated frames grey; interaction: ``<sample>_A_sheet.png`` and ``<sample>_B_sheet.png``) and with ``--gif``
an animated ``<sample>.gif`` (both characters for interaction).

Every output folder also gets ``infill.json`` (checkpoint, step, inputs, seed).  Errors caused by the inputs
print one line ``inbetween: error: ...`` and exit with status 2; nothing is written to ``--out`` then (the
files are written to a temporary folder and moved in at the end).

``inbetween preview FILE.bvh [--frames a:b] [--every N] [--keyframes 0,30] [--out DIR] [--gif]`` draws a BVH
file (e.g. an infill output) as ``<out>/<name>_sheet.png`` (and ``<out>/<name>.gif``), same error contract.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile

MODELS = ("scvae", "cae", "interaction")
MAX_SAMPLES = 1000
_MODEL_OPTIONS = {"scvae": ("start", "end", "frames"), "cae": ("bvh", "gaps"),
                  "interaction": ("a", "b", "key_a", "key_b", "frames")}


class UserError(Exception):
    """A problem with the user's inputs; ``str(err)`` is the one-line message (exit status 2)."""


class _ArgError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):                     # one line instead of usage + message, status 2
        raise _ArgError(message)


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="inbetween", description="In-betweening of your own BVH files with a trained checkpoint.",
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    p = sub.add_parser("infill", help="generate transitions / fill gaps with a trained checkpoint",
                       description="Generate transitions or fill gaps of BVH files with a trained checkpoint.",
                       epilog="examples:\n" + __doc__.split("Examples::\n\n", 1)[1].split("\n\n", 1)[0],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True, help="scvae | cae | interaction")
    p.add_argument("--ckpt", required=True, help="training run folder (with checkpoints/)")
    p.add_argument("--out", required=True, help="output folder (created; must be empty unless --overwrite)")
    p.add_argument("--start", help="scvae: start keyframe FILE.bvh[:FRAME] (default frame 0)")
    p.add_argument("--end", help="scvae: end keyframe FILE.bvh[:FRAME] (default last frame)")
    p.add_argument("--bvh", help="cae: the BVH file to fill")
    p.add_argument("--gaps", help="cae: frame ranges to fill, START:STOP[,START:STOP...] (STOP exclusive)")
    p.add_argument("--a", help="interaction: character A FILE.bvh[:START_FRAME] (default last frame)")
    p.add_argument("--b", help="interaction: character B FILE.bvh[:START_FRAME] (default last frame)")
    p.add_argument("--key-a", help="interaction: A's keyframe FILE.bvh[:FRAME] (default last frame)")
    p.add_argument("--key-b", help="interaction: B's keyframe FILE.bvh[:FRAME] (default last frame)")
    p.add_argument("--frames", type=int, help="scvae / interaction: generated frames between the keyframes")
    p.add_argument("--samples", type=int, default=1, help="scvae / interaction: number of samples (default 1)")
    p.add_argument("--seed", type=int, default=0, help="PRNG seed (default 0)")
    p.add_argument("--overwrite", action="store_true",
                   help="allow a non-empty --out (same-named files are replaced, others kept)")
    p.add_argument("--preview", action="store_true",
                   help="also write a contact sheet PNG per sample (keyframes black, generated frames grey)")
    p.add_argument("--gif", action="store_true", help="also write an animated GIF per sample (implies --preview)")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    v = sub.add_parser("preview", help="draw a BVH file as a contact sheet PNG (and an animated GIF)",
                       description="Draw a BVH file: <out>/<name>_sheet.png (and <out>/<name>.gif); same-named "
                                   "files in --out are replaced.")
    v.add_argument("bvh", metavar="FILE.bvh", help="the BVH file")
    v.add_argument("--frames", type=_frame_range, default=(None, None),
                   help="frame range a:b of the file (b exclusive, either side may be left out; negative numbers "
                        "count from the end: --frames=-30:)")
    v.add_argument("--every", type=int, default=5, help="draw every N-th frame on the sheet (default 5)")
    v.add_argument("--keyframes", type=_int_list, default=[], help="frame numbers drawn black, e.g. 0,30")
    v.add_argument("--out", default=".", help="output folder (created if missing; default: current folder)")
    v.add_argument("--gif", action="store_true", help="also write an animated GIF")
    v.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    return ap


def _frame_range(text: str) -> tuple:
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        return tuple(int(p) if p.strip() else None for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a:b (frame numbers), got {text!r}") from None


def _int_list(text: str) -> list:
    try:
        return [int(k) for k in text.split(",") if k.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated frame numbers, got {text!r}") from None


def main(argv=None) -> int:
    """Entry point of the ``inbetween`` console script; returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = build_parser().parse_args(argv)
    except _ArgError as e:
        return _fail(str(e))
    except SystemExit as e:                       # --help
        return e.code if isinstance(e.code, int) else 0
    if args.command is None:
        build_parser().print_help(sys.stderr)
        return 2
    try:
        return _preview(args) if args.command == "preview" else _infill(args)
    except (UserError, ValueError, OSError) as e:
        if args.traceback:
            raise
        return _fail(str(e))
    except Exception as e:                        # a bug, not the user's fault: one line unless --traceback
        if args.traceback:
            raise
        print(f"inbetween: internal error: {type(e).__name__}: {_one_line(str(e))} (rerun with --traceback)",
              file=sys.stderr)
        return 1


def _one_line(msg: str) -> str:
    return "; ".join(s.strip() for s in msg.splitlines() if s.strip()) or "unknown problem"


def _fail(msg: str) -> int:
    print(f"inbetween: error: {_one_line(msg)}", file=sys.stderr)
    return 2


def _check_common(args) -> None:
    if args.model not in MODELS:
        raise UserError(f"unknown model {args.model!r} (choose {', '.join(MODELS)})")
    used = _MODEL_OPTIONS[args.model]
    for o in sorted({o for opts in _MODEL_OPTIONS.values() for o in opts} - set(used)):
        if getattr(args, o) is not None:
            raise UserError(f"--{o.replace('_', '-')} is not used with --model {args.model}")
    for o in used:
        if getattr(args, o) is None:
            raise UserError(f"--model {args.model} needs --{o.replace('_', '-')}")
    if args.frames is not None and args.frames < 1:
        raise UserError(f"--frames must be a positive number of frames, got {args.frames}")
    if not 1 <= args.samples <= MAX_SAMPLES:
        raise UserError(f"--samples must be between 1 and {MAX_SAMPLES}, got {args.samples}")
    if not 0 <= args.seed < 2 ** 32:
        raise UserError(f"--seed must be between 0 and 2**32 - 1, got {args.seed}")
    _check_out(args.out, args.overwrite)


def _check_out(out_arg: str, overwrite: bool) -> None:
    out = os.path.abspath(out_arg)
    if os.path.exists(out) and not os.path.isdir(out):
        raise UserError(f"--out {out_arg}: exists and is not a folder")
    if os.path.isdir(out) and os.listdir(out) and not overwrite:
        raise UserError(f"--out {out_arg}: folder is not empty (choose a new folder or pass --overwrite)")


def _preview(args) -> int:
    from inbetween_jax.cli_infill import read_motion
    from inbetween_jax.viz import bvh_previews
    if args.every < 1:
        raise UserError(f"--every must be >= 1, got {args.every}")
    _check_out(args.out, overwrite=True)
    motion = read_motion(args.bvh)
    name = os.path.splitext(os.path.basename(args.bvh))[0]
    files = bvh_previews(motion, name, args.frames, args.every, args.keyframes, args.gif)
    _write_outputs(args.out, files)
    for f in files:
        print(os.path.join(args.out, f))
    return 0


def _infill(args) -> int:
    _check_common(args)
    args.preview = args.preview or args.gif
    from inbetween_jax.train import enable_compilation_cache
    try:
        enable_compilation_cache()                # compiled samplers are reused by the next call
    except OSError:
        pass                                      # an unwritable cache folder only costs compile time
    files, summary = {"scvae": _run_scvae, "cae": _run_cae, "interaction": _run_interaction}[args.model](args)
    summary.update(model=args.model, checkpoint=os.path.abspath(args.ckpt), seed=args.seed)
    files["infill.json"] = lambda path: _write_json(path, summary)
    _write_outputs(args.out, files)
    print(f"inbetween: wrote {len(files)} files to {args.out}")
    return 0


def _write_json(path, obj) -> None:
    with open(path, "w") as f:
        json.dump(obj, f, indent=1)


def _write_outputs(out: str, files: dict) -> None:
    """Write ``{name: writer(path)}`` into a temporary folder (a sibling of ``out``, or inside ``out`` when it
    exists), then move them into ``out``; on any error nothing reaches ``out``."""
    out = os.path.abspath(out)
    parent = out if os.path.isdir(out) else os.path.dirname(out)
    os.makedirs(parent, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=f".{os.path.basename(out)}.tmp-", dir=parent)
    try:
        for name, writer in files.items():
            writer(os.path.join(tmp, name))
        if not os.path.exists(out):
            os.rename(tmp, out)
            return
        for name in files:
            os.replace(os.path.join(tmp, name), os.path.join(out, name))
    finally:
        if os.path.isdir(tmp):
            shutil.rmtree(tmp, ignore_errors=True)


def _bvh_writer(motion):
    from inbetween_jax.data import write_bvh
    return lambda path: write_bvh(path, motion)


def _names(n: int) -> list:
    width = max(2, len(str(n - 1)))
    return [f"sample_{i:0{width}d}" for i in range(n)]


def _add_previews(files: dict, args, name: str, motions: list, generated=None, what: str = "keyframes") -> None:
    """With ``--preview``: add ``name``'s contact sheet(s) (and ``--gif``) writers to ``files``.

    motions: [Motion] or [Motion A, Motion B] of T frames each; generated: (T,) bool, the frames drawn grey
    (default: all but the first and last).  The other frames are drawn black where the sheet shows them
    (every ``ceil(T / 16)``-th frame) and next to generated frames.
    """
    if not args.preview:
        return
    import numpy as np

    from inbetween_jax.viz import motion_positions, preview_writers
    pos = [motion_positions(m) for m in motions]
    t = len(pos[0])
    every = max(1, -(-t // 16))
    gen = np.arange(t) % max(t - 1, 1) != 0 if generated is None else np.asarray(generated, bool)
    near = gen.copy()                                                        # generated or next to one
    near[1:] |= gen[:-1]
    near[:-1] |= gen[1:]
    keys = np.flatnonzero(~gen & ((np.arange(t) % every == 0) | near))
    files.update(preview_writers(
        pos[0], motions[0].skeleton.parents, name, fps=motions[0].fps, every=every,
        keyframes=keys, generated=gen, gif=args.gif, stride=max(1, -(-t // 300)),
        title=f"{name}: {what} black, generated grey", positions_b=pos[1] if len(pos) > 1 else None,
        parents_b=motions[-1].skeleton.parents))


def _keyframe(spec, option, default, cache):
    from inbetween_jax.cli_infill import pick_frame, read_motion, split_spec
    path, frame = split_spec(spec, option)
    if path not in cache:
        cache[path] = read_motion(path)
    return path, cache[path], pick_frame(cache[path], path, frame, default, option)


# ----------------------------------------------------------------------------- per model
def _run_scvae(args):
    import dataclasses

    import numpy as np

    from inbetween_jax.cli_infill import (check_skeleton, finite_or_fail, is_lafan1_skeleton,
                                          keyframe_contacts, same_skeleton, scvae_checkpoint, scvae_frame_range,
                                          scvae_infill, scvae_restore)
    from inbetween_jax.data import lafan1
    info = scvae_checkpoint(args.ckpt)
    cache = {}
    sp, sm, sf = _keyframe(args.start, "--start", 0, cache)
    ep, em, ef = _keyframe(args.end, "--end", -1, cache)
    skel = sm.skeleton
    check_skeleton(skel, sp, info["skeleton"], info["num_joints"])
    same_skeleton(em.skeleton, ep, skel, sp)
    lo, hi = scvae_frame_range(info["cfg"])
    if not lo <= args.frames <= hi:
        raise UserError(f"--frames {args.frames}: this S-CVAE checkpoint generates {lo}..{hi} frames between "
                        f"keyframes (trained with train.trans_max={hi})")
    state = scvae_restore(info, skel.num_joints)
    lafan = info["lafan1"] or is_lafan1_skeleton(skel)
    ref = info["skeleton"] or skel
    fa = lafan1.ROOT_FORWARD_AXIS if lafan else tuple(ref.forward_axis())
    vf = lafan1.CONTACT_VELFACTOR if lafan else info["velfactor"]
    start = {"q": sm.local_quats[sf], "r": sm.root_pos[sf], "c": keyframe_contacts(sm, sf, vf)}
    end = {"q": em.local_quats[ef], "r": em.root_pos[ef], "c": keyframe_contacts(em, ef, vf)}
    res = scvae_infill(info["cfg"], state, skel, start, end, args.frames, args.samples, args.seed, fa)
    finite_or_fail(args.ckpt, res["q"], res["r"])
    t = args.frames + 2
    w = (np.arange(t) / (t - 1))[:, None, None]
    base_pos = (1 - w) * sm.local_pos[sf] + w * em.local_pos[ef]       # joints with position channels: lerp
    files = {}
    for name, q, r in zip(_names(args.samples), res["q"], res["r"]):
        pos = base_pos.copy()
        pos[:, 0] = r
        motion = dataclasses.replace(sm, local_quats=q, local_pos=pos)
        files[f"{name}.bvh"] = _bvh_writer(motion)
        _add_previews(files, args, name, [motion])
    return files, {"start": f"{sp}:{sf}", "end": f"{ep}:{ef}", "frames": args.frames, "samples": args.samples,
                   "step": info["step"]}


def _run_cae(args):
    import numpy as np

    from inbetween_jax.cli_infill import (check_skeleton, checkpoint_step, finite_or_fail, parse_gaps, read_json,
                                          read_motion)
    from inbetween_jax.data import Skeleton
    from inbetween_jax.models.cae_infer import process_motion
    from inbetween_jax.models.cae_train import META_FILE, load_trained
    parse_gaps(args.gaps)                                             # syntax first
    _, step = checkpoint_step(args.ckpt)
    meta = read_json(os.path.join(args.ckpt, META_FILE), "not a CAE run folder")
    motion = read_motion(args.bvh)
    check_skeleton(motion.skeleton, args.bvh, Skeleton.from_dict(meta["skeleton"]))
    gaps = parse_gaps(args.gaps, motion.num_frames, args.bvh)
    model = load_trained(args.ckpt, step)
    res = process_motion(model, motion, gaps, seed=args.seed)
    finite_or_fail(args.ckpt, res["positions"], res["motion"].local_quats, res["motion"].local_pos)
    stem = os.path.splitext(os.path.basename(args.bvh))[0]
    pos = res["positions"]
    files = {f"{stem}_filled.bvh": _bvh_writer(res["motion"]),
             f"{stem}_filled.npy": lambda path: _save_npy(path, pos)}
    gen = np.zeros(motion.num_frames, bool)
    for a, b in gaps:
        gen[a:b] = True
    _add_previews(files, args, f"{stem}_filled", [res["motion"]], gen, "known frames")
    return files, {"input": args.bvh, "gaps": gaps, "frames": motion.num_frames, "step": step,
                   "error_cm_mean": res["error_cm"][0], "fk_gap_cm": res["fk_gap_cm"],
                   "refit_frames": int(np.sum(res["frames"]))}


def _save_npy(path, arr) -> None:
    import numpy as np
    with open(path, "wb") as f:                  # np.save(path) would append .npy to the temporary name
        np.save(f, arr)


if __name__ == "__main__":
    sys.exit(main())
