"""``inbetween select-checkpoint`` / ``calibrate-gate`` / ``build-bank``: the steps between a finished training run
and ``inbetween ship-weights``, on validation data only.

    inbetween select-checkpoint RUN_DIR [--source S]       score every checkpoint on the validation split
    inbetween calibrate-gate RUN_DIR [--source S] [--kind K]   the out-of-distribution gate's score and thresholds
    inbetween build-bank RUN_DIR [--split fit] [--mirror] [--set KEY=VALUE ...]   the run's motion bank

``select-checkpoint`` writes ``RUN_DIR/selection.json`` (loading the run then uses that step; ``inbetween train``
does it by itself at the end of a run trained on a ``fit`` split).  ``calibrate-gate`` writes ``RUN_DIR/ood.npz``
and ``ood_calibration.json`` (:func:`inbetween_jax.models.ood_runs.calibrate_run`); the gate is on with
``model.ood_gate=true`` (``inbetween ship-weights RUN_DIR --set model.ood_gate=true``).  ``build-bank`` writes
``RUN_DIR/bank.npz`` from the training files without the validation ones and records ``--set`` switches in
``run.json`` (:func:`inbetween_jax.banks.write_bank`).  The run folder is checked before JAX is loaded.
"""
from __future__ import annotations

import argparse
import importlib.util
import inspect
import json
import os

from inbetween_jax.errors import UserError

_EPILOG = __doc__.split("\n\n", 2)[2]


def add_parser(sub) -> None:
    def one(name, help_text, run):
        p = sub.add_parser(name, help=help_text, description=help_text, epilog=_EPILOG,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("run_dir", metavar="RUN_DIR", help="training run folder (run.json + checkpoints/)")
        p.add_argument("--source", default=None, help="data source (default: the one the run was trained on)")
        p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
        p.set_defaults(run=run)
        return p

    one("select-checkpoint", "choose a run's checkpoint on its validation split", run_select)
    p = one("calibrate-gate", "calibrate a run's out-of-distribution gate on its validation split", run_calibrate)
    p.add_argument("--kind", default=None, choices=("knn", "travel"),
                   help="S-CVAE / CAE: the gate's score, the context's k-NN distance to the training split's or how "
                        "fast the root travels (default travel, the one chosen on the validation subjects for both)")
    p.add_argument("--keep-gate", action="store_true",
                   help="keep the folder's gate and (re)calibrate only what is added to it: the S-CVAE's thresholds "
                        "inside a clip (the frames beside the keyframes known), the CAE's k-NN cap")
    p = one("build-bank", "write a run's motion bank (training files without the validation ones)", run_bank)
    p.add_argument("--split", default="fit", choices=("fit", "train"), help="motions the bank holds (default fit)")
    p.add_argument("--mirror", action="store_true", help="S-CVAE: add each motion's mirror image to the bank")
    p.add_argument("--set", dest="switches", action="append", default=[], metavar="KEY=VALUE",
                   help="bank switch written into run.json, e.g. model.bank_k=8 (repeatable)")


def _run(args, need_checkpoint=True):
    """The run of ``args.run_dir`` (checked before JAX loads) and the data source to use."""
    if not os.path.isdir(args.run_dir):
        raise UserError(f"{args.run_dir}: no such run folder")
    from inbetween_jax.train.run import load_run
    run = load_run(args.run_dir, need_checkpoint=need_checkpoint)
    return run, args.source or run.data.get("source") or "cmu"


def run_select(args) -> int:
    run, source = _run(args, need_checkpoint=False)
    from inbetween_jax.models import REGISTRY
    from inbetween_jax.train.select import select_with_bench
    bench = REGISTRY[run.model].module("bench")
    if not hasattr(bench, "val_score"):
        raise UserError(f"{args.run_dir}: the {run.model} model has no validation score")
    return 0 if select_with_bench(args.run_dir, source, bench) else 1


def run_calibrate(args) -> int:
    run, source = _run(args)
    if importlib.util.find_spec(f"inbetween_jax.models.{run.model}.calibrate") is None:
        raise UserError(f"{args.run_dir}: the {run.model} model has no out-of-distribution gate")
    from inbetween_jax.models.ood_runs import calibrate_run
    calibrate = importlib.import_module(f"inbetween_jax.models.{run.model}.calibrate").calibrate
    if args.kind is not None and "kind" not in inspect.signature(calibrate).parameters:
        raise UserError(f"{args.run_dir}: the {run.model} model's gate has one score (no --kind)")
    if args.keep_gate:
        module = importlib.import_module(f"inbetween_jax.models.{run.model}.calibrate")
        if not hasattr(module, "calibrate_additions") or args.kind is not None:
            raise UserError(f"{args.run_dir}: --keep-gate is for S-CVAE and CAE gates, without --kind")
        from inbetween_jax.models.ood_runs import calibrate_additions_run
        print(json.dumps(calibrate_additions_run(args.run_dir, source), indent=1, default=float))
        return 0
    kwargs = {} if args.kind is None else {"kind": args.kind}
    print(json.dumps(calibrate_run(args.run_dir, source, **kwargs), indent=1, default=float))
    return 0


def run_bank(args) -> int:
    for item in args.switches:
        if "=" not in item or not item.split("=", 1)[0]:
            raise UserError(f"--set {item}: expected KEY=VALUE")
    _run(args, need_checkpoint=False)
    from inbetween_jax.banks import write_bank
    out = write_bank(args.run_dir, args.source, args.split, args.mirror, args.switches)
    bank = out["bank"]
    names = ", ".join(bank.names) if len(bank.names) <= 12 else f"{', '.join(bank.names[:3])}, ..."
    print(f"{out['path']}: {len(bank.names)} clips ({names}), {bank.num_frames} frames, "
          f"{out['bytes'] / 2 ** 20:.2f} MB; switches: {' '.join(args.switches) or 'unchanged'}")
    return 0
