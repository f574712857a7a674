"""Shim for ``inbetween speed`` (:mod:`inbetween_jax.cli.speed_cmd`) with the PyTorch reference beside this script
(``torch_scvae.py``): ``python experiments/bench_speed.py [--results DIR] [--reps N] [--quick] [--source DIR]``."""
import os
import sys

from inbetween_jax.cli import main

if __name__ == "__main__":
    sys.exit(main(["speed", "--torch-ref", os.path.join(os.path.dirname(os.path.abspath(__file__)), "torch_scvae.py")]
                  + sys.argv[1:]))
