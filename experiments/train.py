"""Train one of the models: ``python experiments/train.py MODEL [--source DIR] [--run-dir DIR] [key=value ...]``.

MODEL is ``scvae``, ``cae`` or ``interaction``; the rest is passed to ``experiments/train_<MODEL>.py``.
Data: ``--source`` if given, else ``$LAFAN1_DIR`` if set, else the embedded CMU default.
"""
import importlib
import os
import sys

MODELS = ("scvae", "cae", "interaction")


def main(argv):
    if not argv or argv[0] not in MODELS:
        print(__doc__.strip(), file=sys.stderr)
        print(f"error: first argument must be one of {', '.join(MODELS)}", file=sys.stderr)
        return 2
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    module = importlib.import_module(f"train_{argv[0]}")
    return module.main(argv[1:]) or 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except (OSError, ValueError) as err:  # bad data / config: one line, no traceback
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
