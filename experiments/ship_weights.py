"""Shim for ``inbetween ship-weights RUN_DIR [--step N] [--dtype float16|float32] [--why TEXT] [--out DIR]
[--set KEY=VALUE ...]`` (:mod:`inbetween_jax.cli.ship_weights_cmd`), kept for the commands in docs/results."""
import sys

from inbetween_jax.cli import main

if __name__ == "__main__":
    sys.exit(main(["ship-weights"] + sys.argv[1:]))
