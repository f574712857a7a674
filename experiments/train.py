"""Train one of the models: ``python experiments/train.py MODEL [--source DIR] [--run-dir DIR] [key=value ...]``.

MODEL is ``scvae``, ``cae`` or ``interaction``; the rest is passed to ``experiments/train_<MODEL>.py``.
Data: ``--source`` if given, else ``$LAFAN1_DIR`` if set, else the embedded CMU default.
Bad data, a bad config or a diverging run (NaN / inf loss, reported with its step) prints one line
``train: error: ...`` and exits with status 2.
"""
import importlib
import os
import sys

MODELS = ("scvae", "cae", "interaction")


def _fail(message) -> int:
    text = "; ".join(s.strip() for s in str(message).splitlines() if s.strip())
    print(f"train: error: {text}", file=sys.stderr)
    return 2


def main(argv) -> int:
    argv = list(argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    if argv[0] not in MODELS:
        return _fail(f"unknown model {argv[0]!r}: the first argument must be one of {', '.join(MODELS)}")
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    module = importlib.import_module(f"train_{argv[0]}")
    try:
        return module.main(argv[1:]) or 0
    except (FloatingPointError, ValueError, OSError) as err:   # BVHError and ConfigError are ValueErrors
        return _fail(err)
    except SystemExit as err:                                   # a sub-script's own usage error
        if isinstance(err.code, str):
            return _fail(err.code)
        raise


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
