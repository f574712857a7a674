"""``inbetween ship-weights RUN_DIR``: export a training run's inference weights as shipped weights.

Writes ``<weights folder>/<model>/run.json`` + ``params.npz`` (the weights folder is the package's
``inbetween_jax/assets/weights``, or ``$INBETWEEN_WEIGHTS_DIR``; ``--out DIR`` writes elsewhere): the parameters
``infer.load`` uses (no optimizer state, no discriminators), float16 unless ``--dtype float32``, and prints the
size.  ``inbetween infill --model M`` without ``--ckpt`` and ``inbetween bench`` (no run under ``--runs``) then
use them (:func:`inbetween_jax.shipped.export_run`).  ``--set KEY=VALUE`` records an inference-only switch in
the shipped config (e.g. ``model.refiner=false``).  The run folder, step and switches are checked before JAX is
loaded.
"""
from __future__ import annotations

import argparse
import os

from inbetween_jax.errors import UserError

DTYPES = ("float16", "float32")


def add_parser(sub) -> None:
    p = sub.add_parser("ship-weights", help="export a run's inference weights into the package (shipped weights)",
                       description=__doc__.split("\n\n")[0].split(": ", 1)[1], epilog=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run_dir", metavar="RUN_DIR", help="training run folder (run.json + checkpoints/)")
    p.add_argument("--step", type=int, default=None,
                   help="checkpoint step (default: the step chosen on the validation split, else the latest)")
    p.add_argument("--dtype", default="float16", choices=DTYPES, help="stored dtype (default float16)")
    p.add_argument("--why", default=None, help="how the step was chosen (recorded in run.json)")
    p.add_argument("--out", default=None, help="output folder (default: <weights folder>/<model>)")
    p.add_argument("--set", dest="inference", action="append", default=[], metavar="KEY=VALUE",
                   help="an inference-only switch for the shipped config, e.g. model.refiner=false (repeatable)")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    p.set_defaults(run=run)


def _check(args) -> None:
    if not os.path.isdir(args.run_dir):
        raise UserError(f"{args.run_dir}: no such run folder")
    if args.step is not None and args.step < 0:
        raise UserError(f"--step must be >= 0, got {args.step}")
    for item in args.inference:
        if "=" not in item or not item.split("=", 1)[0]:
            raise UserError(f"--set {item}: expected KEY=VALUE")
    if args.out and os.path.exists(args.out) and not os.path.isdir(args.out):
        raise UserError(f"--out {args.out}: exists and is not a folder")


def run(args) -> int:
    _check(args)
    from inbetween_jax.shipped import export_run, folder_bytes, weights_root
    info = export_run(args.run_dir, args.step, args.out, args.dtype, why=args.why, inference=tuple(args.inference))
    mb = 1024 * 1024
    print(f"{info['model']} step {info['step']}: {info['parameters']:,} parameters ({info['arrays']} arrays, "
          f"{info['dtype']}) -> {info['out_dir']}: {info['bytes'] / mb:.2f} MB "
          f"(checkpoint {info['checkpoint_bytes'] / mb:.2f} MB)")
    print(f"all shipped weights ({weights_root()}): {folder_bytes(weights_root()) / mb:.2f} MB")
    return 0
