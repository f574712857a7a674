"""Export a training run's inference weights into the package (:func:`inbetween_jax.shipped.export_run`).

``python experiments/ship_weights.py RUN_DIR [--step N] [--dtype float16|float32] [--why TEXT] [--out DIR]
[--set KEY=VALUE ...]`` (``--set``: inference-only switches such as ``model.refiner=false``)

Writes ``inbetween_jax/assets/weights/<model>/run.json`` + ``params.npz`` (or ``$INBETWEEN_WEIGHTS_DIR/<model>``,
or ``--out``): the parameters ``infer.load`` uses (no optimizer state, no discriminators), and prints the size.
``inbetween infill --model M`` without ``--ckpt`` and ``inbetween bench`` (no run under ``--runs``) then use them.
"""
from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir", metavar="RUN_DIR", help="training run folder (run.json + checkpoints/)")
    ap.add_argument("--step", type=int, default=None, help="checkpoint step (default: the latest)")
    ap.add_argument("--dtype", default="float16", choices=("float16", "float32"))
    ap.add_argument("--why", default=None, help="how the step was chosen (recorded in run.json)")
    ap.add_argument("--out", default=None, help="output folder (default: <weights folder>/<model>)")
    ap.add_argument("--set", dest="inference", action="append", default=[], metavar="KEY=VALUE",
                    help="an inference-only switch for the shipped config, e.g. model.refiner=false (repeatable)")
    a = ap.parse_args(argv)
    from inbetween_jax.shipped import export_run, folder_bytes, weights_root
    from inbetween_jax.train.run import RunError
    try:
        info = export_run(a.run_dir, a.step, a.out, a.dtype, why=a.why, inference=tuple(a.inference))
    except RunError as e:
        print(f"ship_weights: error: {e}", file=sys.stderr)
        return 2
    mb = 1024 * 1024
    print(f"{info['model']} step {info['step']}: {info['parameters']:,} parameters ({info['arrays']} arrays, "
          f"{info['dtype']}) -> {info['out_dir']}: {info['bytes'] / mb:.2f} MB (checkpoint {info['checkpoint_bytes'] / mb:.2f} MB)")
    print(f"all shipped weights ({weights_root()}): {folder_bytes(weights_root()) / mb:.2f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
