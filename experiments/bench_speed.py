"""Speed section of ``make bench`` (:mod:`inbetween_jax.evaluation.speed`): compiled JAX against the PyTorch-eager
S-CVAE reference (``torch_scvae.py`` beside this script; its rows are skipped when torch is not installed).

``python experiments/bench_speed.py [--source DIR] [--results DIR] [--reps N] [--quick]``
"""
from __future__ import annotations

import argparse
import os
import sys


def torch_reference():
    """The ``torch_scvae`` module of this folder when torch is installed, else None."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import torch_scvae
    return torch_scvae if torch_scvae.available() else None


def run(source=None, results_dir="results", reps=10, quick=False) -> dict:
    from inbetween_jax.evaluation import speed
    return speed.run(source, results_dir, reps, quick, torch_ref=torch_reference())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", default=None)
    ap.add_argument("--results", default="results")
    ap.add_argument("--reps", type=int, default=10)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    print(run(a.source, a.results, a.reps, a.quick)["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
