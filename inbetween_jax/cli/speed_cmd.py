"""``inbetween speed``: the speed section of ``make bench`` -- compiled JAX against a PyTorch-eager reference.

Times the S-CVAE and CAE training steps (JAX against the package's PyTorch references,
:mod:`inbetween_jax.evaluation.torch_ref`, eager and compiled), S-CVAE, CAE and interaction inference and every
compile (:mod:`inbetween_jax.evaluation.speed`); writes ``<results>/speed.md`` and ``speed.json``, and appends the
section to ``<results>/bench.md`` / ``bench.json`` (key ``speed``) when ``inbetween bench`` wrote them there.  The
PyTorch rows need the ``bench`` extra (``pip install "inbetween_jax[bench]"``: torch; ``make bench`` installs it);
without it they read "skipped".  ``--torch-ref FILE.py`` times another S-CVAE reference module instead (one with
``available()``, ``make_step(...)`` and ``torch``; a ``cae.py`` beside it is the CAE reference).  Arguments and
files are checked before JAX is loaded.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from inbetween_jax.errors import UserError


def add_parser(sub) -> None:
    p = sub.add_parser("speed", help="speed section: compiled JAX against PyTorch eager, compile times",
                       description=__doc__.split("\n\n")[0].split(": ", 1)[1], epilog=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--source", default=None,
                   help="LaFAN1 / BVH folder, 'embedded' or 'cmu' (default: $LAFAN1_DIR, else the embedded CMU clips)")
    p.add_argument("--results", default="results", help="output folder (default results)")
    p.add_argument("--reps", type=int, default=10, help="timed calls per row (default 10)")
    p.add_argument("--quick", action="store_true", help="fewer rows and smaller sizes")
    p.add_argument("--torch-ref", default=None, metavar="FILE.py",
                   help="another PyTorch S-CVAE reference module (default: inbetween_jax.evaluation.torch_ref)")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    p.set_defaults(run=run)


def _check(args) -> None:
    if args.reps < 1:
        raise UserError(f"--reps must be >= 1, got {args.reps}")
    if args.source not in (None, "embedded", "cmu") and not os.path.isdir(args.source):
        raise UserError(f"--source {args.source}: no such folder")
    if args.torch_ref and not os.path.isfile(args.torch_ref):
        raise UserError(f"--torch-ref {args.torch_ref}: no such file")
    if os.path.exists(args.results) and not os.path.isdir(args.results):
        raise UserError(f"--results {args.results}: exists and is not a folder")


def load_torch_ref(path: str | None):
    """The reference module of ``path`` (imported from its file); without a path the package's own
    (:mod:`inbetween_jax.evaluation.torch_ref.scvae`) when torch is installed, else None."""
    import importlib.util
    if not path:
        if importlib.util.find_spec("torch") is None:
            return None
        from inbetween_jax.evaluation.torch_ref import scvae
        return scvae
    spec = importlib.util.spec_from_file_location("inbetween_torch_ref", os.path.abspath(path))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for name in ("available", "make_step"):
        if not callable(getattr(module, name, None)):
            raise UserError(f"--torch-ref {path}: defines no {name}() (not the PyTorch reference module)")
    return module


def skip_reason() -> str:
    """Why the PyTorch rows are skipped when no reference module is given."""
    import importlib.util
    if importlib.util.find_spec("torch") is None:
        return 'torch not installed: pip install "inbetween_jax[bench]"'
    return "no PyTorch reference module"


def append_to_bench(out: dict, results_dir: str) -> bool:
    """Append the speed section to ``bench.md`` and ``bench.json`` (key ``speed``) of ``results_dir`` when both
    exist; returns whether it did."""
    md, js = os.path.join(results_dir, "bench.md"), os.path.join(results_dir, "bench.json")
    if not (os.path.exists(md) and os.path.exists(js)):
        return False
    with open(md, "a") as f:
        f.write("\n" + out["markdown"] + "\n")
    with open(js) as f:
        results = json.load(f)
    results["speed"] = {k: v for k, v in out.items() if k != "markdown"}
    tmp = js + ".tmp"
    with open(tmp, "w") as f:
        json.dump(results, f, indent=1, default=float)
    os.replace(tmp, js)
    return True


def run(args) -> int:
    _check(args)
    torch_ref = load_torch_ref(args.torch_ref)
    print("bench: speed section (JAX against PyTorch eager)", file=sys.stderr, flush=True)
    from inbetween_jax.evaluation import speed
    out = speed.run(args.source, args.results, args.reps, args.quick, torch_ref=torch_ref,
                    torch_skip=None if torch_ref is not None else skip_reason())
    append_to_bench(out, args.results)
    print(out["markdown"])
    return 0
