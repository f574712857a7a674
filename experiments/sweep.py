"""Shim for ``inbetween sweep [--seeds 3] [--rows ...] [key=value ...]`` (:mod:`inbetween_jax.cli.sweep_cmd`), kept
for the commands in docs/results."""
import sys

from inbetween_jax.cli import main

if __name__ == "__main__":
    sys.exit(main(["sweep"] + sys.argv[1:]))
