"""Choose a run's checkpoint on the validation split of its training source (never the test windows).

    python experiments/select_checkpoint.py RUN_DIR [--source SOURCE]

Scores every checkpoint with the model's ``bench.val_score`` and writes ``RUN_DIR/selection.json``; loading the
run (bench, infill, ship_weights) then uses that step.  ``inbetween train`` does this by itself at the end of a
run trained with ``train.split=fit``; this script is for runs stopped early or trained before that.
"""
import argparse
import sys

from inbetween_jax.models import REGISTRY
from inbetween_jax.train.run import RunError, load_run
from inbetween_jax.train.select import select_with_bench


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--source", default=None, help="data source (default: the one the run was trained on)")
    args = p.parse_args(argv)
    try:
        run = load_run(args.run_dir, need_checkpoint=False)
    except RunError as e:
        print(f"select_checkpoint: {e}", file=sys.stderr)
        return 2
    bench = REGISTRY[run.model].module("bench")
    if not hasattr(bench, "val_score"):
        print(f"select_checkpoint: {run.model} has no validation score", file=sys.stderr)
        return 2
    source = args.source or run.data.get("source")
    out = select_with_bench(args.run_dir, source, bench)
    return 0 if out else 1


if __name__ == "__main__":
    sys.exit(main())
