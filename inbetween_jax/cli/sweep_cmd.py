"""``inbetween sweep``: ablation sweep with seed repeats (the S-CVAE paper's Table 6, mean ± std over seeds).

Every row (the full model, then the full model with one switch off) trains all its seeds in one vmapped
program, then samples ``--samples`` transitions of ``--frames`` frames per test window; writes
``<results>/sweep_<model>.md`` and ``.json`` (:mod:`inbetween_jax.train.sweep`).  ``key=value`` overrides apply
to every row.  Rows, presets, overrides and the source are checked before JAX is loaded.

examples:
  inbetween sweep --seeds 3                                  # tiny preset, 200 steps, embedded CMU clips
  inbetween sweep --rows full,no_d --seeds 2 --steps 50 train.lr=0.001
"""
from __future__ import annotations

import argparse
import os

from inbetween_jax.errors import UserError
from inbetween_jax.train.ablations import ABLATIONS, DEFAULT_STEPS, SWEEP_PRESETS


def add_parser(sub) -> None:
    p = sub.add_parser("sweep", help="ablation sweep with seed repeats (mean ± std over seeds)",
                       description=__doc__.split("\n\n")[0].split(": ", 1)[1], epilog=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", default="scvae", choices=tuple(ABLATIONS), help="model (default scvae)")
    p.add_argument("--source", default=None,
                   help="LaFAN1 / BVH folder or 'embedded' (default: $LAFAN1_DIR, else the embedded CMU clips)")
    p.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1 per row (default 3)")
    p.add_argument("--steps", type=int, default=None,
                   help="training steps (default: " + ", ".join(f"{n} {k}" for k, n in DEFAULT_STEPS.items()) + ")")
    p.add_argument("--preset", default="tiny", choices=SWEEP_PRESETS, help="config preset (default tiny)")
    p.add_argument("--rows", default=None,
                   help=f"comma list of rows (default all; scvae: {', '.join(ABLATIONS['scvae'])})")
    p.add_argument("--frames", type=int, default=30, help="transition length trained and evaluated (default 30)")
    p.add_argument("--samples", type=int, default=5, help="sampled transitions per test window (default 5)")
    p.add_argument("--results", default="results", help="output folder (default results)")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    p.add_argument("overrides", nargs="*", metavar="key=value", help="config overrides (every row)")
    p.set_defaults(run=run)


def _check(args) -> list | None:
    rows = [r.strip() for r in args.rows.split(",") if r.strip()] if args.rows else None
    known = ABLATIONS[args.model]
    for row in rows or ():
        if row not in known:
            raise UserError(f"--rows: unknown row {row!r} (choose {', '.join(known)})")
    for name in ("seeds", "frames", "samples") + (("steps",) if args.steps is not None else ()):
        if getattr(args, name) < 1:
            raise UserError(f"--{name} must be >= 1, got {getattr(args, name)}")
    if args.source not in (None, "embedded", "cmu") and not os.path.isdir(args.source):
        raise UserError(f"--source {args.source}: no such folder")
    if os.path.exists(args.results) and not os.path.isdir(args.results):
        raise UserError(f"--results {args.results}: exists and is not a folder")
    from inbetween_jax.models import get_spec
    from inbetween_jax.train.config import apply_overrides
    apply_overrides(get_spec(args.model).get_config(args.preset), list(args.overrides))   # bad keys: before JAX
    return rows


def run(args) -> int:
    rows = _check(args)
    from inbetween_jax.train.sweep import run as run_sweep
    out = run_sweep(args.source, args.results, args.preset, rows, args.seeds, args.steps, args.frames, args.samples,
                    args.overrides, model=args.model)
    print(out["markdown"])
    return 0
