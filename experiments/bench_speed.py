"""Speed section of ``make bench`` (:mod:`inbetween_jax.evaluation.speed`): compiled JAX against the PyTorch-eager
S-CVAE reference (``torch_scvae.py`` beside this script; its rows are skipped when torch is not installed).
Appended to ``<results>/bench.md`` and ``bench.json`` (key ``speed``) when ``inbetween bench`` wrote them.

``python experiments/bench_speed.py [--source DIR] [--results DIR] [--reps N] [--quick]``
"""
from __future__ import annotations

import argparse
import json
import os
import sys


def torch_reference():
    """The ``torch_scvae`` module of this folder (on ``sys.path`` as the script's own) when torch is installed."""
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
    print("bench: speed section (JAX against PyTorch eager)", file=sys.stderr, flush=True)
    out = run(a.source, a.results, a.reps, a.quick)
    md, js = os.path.join(a.results, "bench.md"), os.path.join(a.results, "bench.json")
    if os.path.exists(md) and os.path.exists(js):
        with open(md, "a") as f:
            f.write("\n" + out["markdown"] + "\n")
        with open(js) as f:
            results = json.load(f)
        results["speed"] = {k: v for k, v in out.items() if k != "markdown"}
        with open(js, "w") as f:
            json.dump(results, f, indent=1, default=float)
    print(out["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
