"""Ablation sweep with seed repeats (S-CVAE paper, Table 6): every row trains all its seeds in one program.

    python experiments/sweep.py [--model scvae] [--source DIR] [--seeds 3] [--steps 200] [--preset tiny]
        [--rows full,no_bs,...] [--frames 30] [--samples 5] [--results results] [key=value ...]

Writes ``<results>/sweep_<model>.md`` and ``.json`` (see :mod:`inbetween_jax.train.sweep`).
"""
from __future__ import annotations

import argparse
import sys


def main(argv: list[str]) -> int:
    from inbetween_jax.train.sweep import ABLATIONS, run
    ap = argparse.ArgumentParser(prog="sweep", description=__doc__.split("\n")[0])
    ap.add_argument("--model", default="scvae", choices=tuple(ABLATIONS))
    ap.add_argument("--source", default=None, help="LaFAN1 / BVH folder or 'embedded' (default: $LAFAN1_DIR, "
                                                   "else the embedded CMU set)")
    ap.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1 per row")
    ap.add_argument("--steps", type=int, default=None, help="train steps (default: 200 tiny, 2000 cpu, 20000 paper)")
    ap.add_argument("--preset", default="tiny", choices=("tiny", "cpu", "paper"))
    ap.add_argument("--rows", default=None, help="comma list of rows (default: all; scvae: "
                                                 f"{', '.join(ABLATIONS['scvae'])})")
    ap.add_argument("--frames", type=int, default=30, help="transition length trained and evaluated")
    ap.add_argument("--samples", type=int, default=5, help="sampled transitions per test window")
    ap.add_argument("--results", default="results")
    ap.add_argument("overrides", nargs="*", help="config overrides key=value (every row)")
    args = ap.parse_args(argv)
    rows = [r.strip() for r in args.rows.split(",") if r.strip()] if args.rows else None
    try:
        out = run(args.source, args.results, args.preset, rows, args.seeds, args.steps, args.frames, args.samples,
                  args.overrides, model=args.model)
    except (OSError, ValueError) as err:      # ConfigError / unknown row / bad source: one line
        print(f"sweep: error: {err}", file=sys.stderr)
        return 2
    print(out["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
