"""Preview a BVH file: same as ``inbetween preview`` (see ``inbetween preview --help``).

    python experiments/preview.py FILE.bvh [--frames a:b] [--every N] [--keyframes 0,30] [--out DIR] [--gif]

Writes ``<out>/<name>_sheet.png`` (and ``<out>/<name>.gif``); errors print one line ``inbetween: error: ...``
and exit with status 2, writing nothing.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from inbetween_jax.cli import main as _cli_main  # noqa: E402


def main(argv=None) -> int:
    return _cli_main(["preview"] + list(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    sys.exit(main())
