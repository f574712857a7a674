"""``inbetween infill`` (in-between users' BVH files with a trained run) and ``inbetween preview`` (draw a BVH).

Outputs are BVH files on the input's skeleton (same joint names, offsets and channel layout) plus
``infill.json`` (run folder, step, inputs, seed); ``--preview`` adds a contact sheet per sample (keyframes /
known frames black, generated frames grey), ``--gif`` an animation.  Every model says which options it needs
(``INFILL_OPTIONS`` of its package).  Without ``--ckpt`` the weights shipped in the package for ``--model``
are used (:mod:`inbetween_jax.shipped`).  Errors caused by the inputs print one line and write nothing.
"""
from __future__ import annotations

import argparse
import os
import sys

from inbetween_jax.errors import UserError
from inbetween_jax.models import MODELS, REGISTRY

MAX_SAMPLES = 1000
EXAMPLES = """examples:
  inbetween infill --model scvae --start a.bvh:0 --end b.bvh:120 --frames 30 --out out/   (shipped weights)
  inbetween infill --model scvae --ckpt runs/scvae --start a.bvh:0 --end b.bvh:120 --frames 30 --samples 10 --out out/
  inbetween infill --model cae --ckpt runs/cae/cae --bvh in.bvh --gaps 100:160,300:420 --out out/ --preview
  inbetween infill --model interaction --a a.bvh:40 --b b.bvh:40 \\
      --key-a a.bvh:90 --key-b b.bvh:90 --frames 50 --samples 3 --out out/ --preview --gif"""


def _model_options() -> dict:
    """``{dest: (metavar, help, [models])}`` over every registered model."""
    opts = {}
    for name in MODELS:
        for dest, (metavar, text) in REGISTRY[name].infill_options.items():
            entry = opts.setdefault(dest, [metavar, f"{name}: {text}", []])
            if name not in entry[1]:
                entry[1] = f"{name} / {entry[1]}"
            entry[2].append(name)
    return opts


def add_parser(sub) -> None:
    p = sub.add_parser("infill", help="generate transitions / fill gaps of BVH files with a trained run",
                       description=__doc__.split("\n\n")[1].replace("\n", " "), epilog=EXAMPLES,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True, help=" | ".join(MODELS))
    p.add_argument("--ckpt", default=None, metavar="RUN_DIR",
                   help="training run folder (run.json + checkpoints/; default: the weights shipped for --model)")
    p.add_argument("--out", required=True, help="output folder (created; must be empty unless --overwrite)")
    for dest, (metavar, text, _) in _model_options().items():
        p.add_argument("--" + dest.replace("_", "-"), dest=dest, metavar=metavar, help=text,
                       type=int if metavar == "N" else str)
    p.add_argument("--samples", type=int, default=1, help="number of samples (default 1)")
    p.add_argument("--seed", type=int, default=0, help="PRNG seed (default 0)")
    p.add_argument("--step", type=int, default=None, help="checkpoint step to use (default: the latest)")
    p.add_argument("--overwrite", action="store_true",
                   help="allow a non-empty --out (same-named files are replaced, others kept)")
    p.add_argument("--preview", action="store_true", help="also write a contact sheet PNG per sample")
    p.add_argument("--gif", action="store_true", help="also write an animated GIF per sample (implies --preview)")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    p.set_defaults(run=run_infill)

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
    v.set_defaults(run=run_preview)


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


def _check_file(path: str) -> None:
    if os.path.isdir(path):
        raise UserError(f"{path}: is a directory, not a BVH file")
    if not os.path.exists(path):
        raise UserError(f"{path}: file not found")


def check_args(args) -> None:
    """Everything that can be checked without JAX: options per model, ranges, input files, ``--out``."""
    from inbetween_jax.cli.outputs import check_out
    from inbetween_jax.data.user_input import split_spec
    if args.model not in REGISTRY:
        raise UserError(f"unknown model {args.model!r} (choose {', '.join(MODELS)})")
    options = _model_options()
    used = REGISTRY[args.model].infill_options
    for dest in sorted(set(options) - set(used)):
        if getattr(args, dest) is not None:
            raise UserError(f"--{dest.replace('_', '-')} is not used with --model {args.model}")
    for dest, (metavar, _) in used.items():
        value = getattr(args, dest)
        if value is None:
            raise UserError(f"--model {args.model} needs --{dest.replace('_', '-')}")
        if metavar == "N" and value < 1:
            raise UserError(f"--{dest.replace('_', '-')} must be a positive number of frames, got {value}")
        if metavar.startswith("START:STOP"):
            from inbetween_jax.data.user_input import parse_gaps
            parse_gaps(value)
        if metavar.startswith("FILE"):
            path, _ = split_spec(value, "--" + dest.replace("_", "-"))
            _check_file(path)
    if not 1 <= args.samples <= MAX_SAMPLES:
        raise UserError(f"--samples must be between 1 and {MAX_SAMPLES}, got {args.samples}")
    if not 0 <= args.seed < 2 ** 32:
        raise UserError(f"--seed must be between 0 and 2**32 - 1, got {args.seed}")
    check_out(args.out, args.overwrite)


def load_checked_run(args):
    """The ``--ckpt`` run folder (default: the shipped weights of ``--model``), checked to hold a run of
    ``--model`` (one-line UserError otherwise)."""
    from inbetween_jax.train.run import RunError, load_run
    if args.ckpt is None:
        from inbetween_jax.shipped import shipped_run
        try:
            run = shipped_run(args.model)
        except RunError as e:
            raise UserError(str(e)) from None
        if run is None:
            raise UserError(f"no trained weights ship for --model {args.model}; pass --ckpt RUN_DIR (a run of "
                            f"`inbetween train {args.model}`)")
        if args.step is not None and args.step != run.step:
            raise UserError(f"--step {args.step}: the shipped {args.model} weights hold step {run.step} only "
                            "(pass --ckpt RUN_DIR for other steps)")
        print(f"inbetween: using the shipped {args.model} weights (step {run.step}, trained on "
              f"{run.shipped.get('data_source') or 'unknown data'})", file=sys.stderr)
        return run
    try:
        run = load_run(args.ckpt, args.step)
    except RunError as e:
        raise UserError(str(e)) from None
    if run.model != args.model:
        raise UserError(f"{args.ckpt}: holds a run of model {run.model!r}, not {args.model!r} "
                        f"(pass --model {run.model})")
    return run


def run_infill(args) -> int:
    from inbetween_jax.cli.outputs import add_previews, add_samples_sheet, bvh_writer, json_writer, write_outputs
    check_args(args)
    args.preview = args.preview or args.gif
    run = load_checked_run(args)
    from inbetween_jax.train.loop import enable_compilation_cache
    try:
        enable_compilation_cache()                # compiled samplers are reused by the next call
    except OSError:
        pass                                      # an unwritable cache folder only costs compile time
    result = REGISTRY[args.model].infill(args, run)
    files = {}
    for name, motions, generated in result.samples:
        if len(motions) == 1:
            files[f"{name}.bvh"] = bvh_writer(motions[0])
        else:
            for c, motion in enumerate(motions):
                files[f"{name}_{'ABCDEFGH'[c]}.bvh"] = bvh_writer(motion)
        if args.preview:
            add_previews(files, name, motions, generated, result.what, gif=args.gif)
    if args.preview and len(result.samples) > 1:          # all samples overlaid: one sheet per character
        chars = min(len(m) for _, m, _ in result.samples)
        for c in range(chars):
            name = "samples_sheet" if chars == 1 else f"samples_sheet_{'ABCDEFGH'[c]}"
            add_samples_sheet(files, [m[c] for _, m, _ in result.samples], result.what, name,
                              "" if chars == 1 else f"character {'ABCDEFGH'[c]}")
    files.update(result.extra_files)
    summary = dict(result.summary, model=args.model, checkpoint=run.run_dir, step=run.step, seed=args.seed,
                   weights="shipped" if run.weights else "checkpoint")
    files["infill.json"] = json_writer(summary)
    for note in result.notes:
        print(f"inbetween: note: {note}", file=sys.stderr)
    write_outputs(args.out, files)
    print(f"inbetween: wrote {len(files)} files to {args.out}")
    return 0


def run_preview(args) -> int:
    from inbetween_jax.cli.outputs import check_out, write_outputs
    from inbetween_jax.data.user_input import read_motion
    if args.every < 1:
        raise UserError(f"--every must be >= 1, got {args.every}")
    _check_file(args.bvh)
    check_out(args.out, overwrite=True)
    motion = read_motion(args.bvh)
    from inbetween_jax.viz import bvh_previews
    name = os.path.splitext(os.path.basename(args.bvh))[0]
    files = bvh_previews(motion, name, args.frames, args.every, args.keyframes, args.gif,
                         progress=drawing_progress(sys.stderr.isatty()))
    write_outputs(args.out, files)
    for f in files:
        print(os.path.join(args.out, f))
    return 0


def drawing_progress(live: bool):
    """``progress(done, total)`` for the previews: a live counter on a terminal, else a line at the end of each
    file (``preview: drawing 400/400``)."""
    def progress(done: int, total: int) -> None:
        if live:
            print(f"\rpreview: drawing {done}/{total}", end="\n" if done == total else "", file=sys.stderr,
                  flush=True)
        elif done == total:
            print(f"preview: drew {total} frames", file=sys.stderr, flush=True)
    return progress
