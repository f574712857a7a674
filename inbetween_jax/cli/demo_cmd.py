"""``inbetween demo``: tiny runs of every registered model, then ``inbetween infill --preview`` on shipped BVH files.

1. trains each model with its ``tiny`` preset for ``--steps`` steps on the embedded CMU clips into
   ``<runs>/<model>`` (replaced on every run);
2. runs each model's ``inbetween infill`` command (printed as a shell command) on clips of
   ``inbetween_jax/assets/cmu30/`` with ``--preview --gif`` into ``<results>/<model>`` (replaced too);
3. prints the written files.
The checkpoints are tiny and barely trained: the demo shows the plumbing (train -> infill -> BVH + previews),
not the quality of the models.  The two top folders are only emptied when they hold the demo's marker file.
"""
from __future__ import annotations

import argparse
import os
import shlex
import shutil
import time

from inbetween_jax.errors import UserError
from inbetween_jax.models import MODELS

ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "assets", "cmu30")
MARKER = ".inbetween_demo"
NOTICE = ("NOTE: the demo checkpoints are TINY and BARELY TRAINED ({steps} steps each): this is a plumbing demo\n"
          "      (train -> infill -> BVH + previews), not a quality demo -- expect poor, unnatural motion.\n"
          "      Real runs: `inbetween train MODEL`, results and commands in docs/results/.")


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help="tiny end-to-end demo: train each model a few steps, infill shipped clips",
                       description=__doc__.split("\n\n")[0].split(": ", 1)[1],
                       epilog=__doc__.split("\n\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--steps", type=int, default=10, help="training steps per model (default 10)")
    p.add_argument("--runs", default=os.path.join("runs", "demo"), help="run folders go to RUNS/<model>")
    p.add_argument("--results", default=os.path.join("results", "demo"), help="outputs go to RESULTS/<model>")
    p.add_argument("--no-gif", action="store_true", help="contact sheets only (faster)")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    p.set_defaults(run=run)


def infill_argv(model: str, run_dir: str, out: str, gif: bool) -> list:
    """``inbetween`` arguments of the demo's in-betweening of two walking clips (86 and 76 frames)."""
    from inbetween_jax.models import REGISTRY
    a, b = (_show(os.path.join(ASSETS, f)) for f in ("02_01.bvh", "02_02.bvh"))
    inputs = {
        "scvae": ["--start", f"{a}:20", "--end", f"{b}:40", "--samples", "3",
                  "--frames", str(REGISTRY["scvae"].get_config("tiny").data.trans_max)],   # the tiny preset's longest
        "cae": ["--bvh", a, "--gaps", "20:40,55:70"],
        "interaction": ["--a", f"{a}:30", "--b", f"{b}:30", "--key-a", f"{a}:70", "--key-b", f"{b}:70",
                        "--frames", "39", "--samples", "2"],
    }[model]
    return ["infill", "--model", model, "--ckpt", run_dir] + inputs + ["--out", out, "--preview"] + \
        (["--gif"] if gif else [])


def _show(path: str) -> str:
    """``path`` relative to the current folder when it lies below it (shorter commands to copy)."""
    rel = os.path.relpath(path)
    return path if rel.startswith("..") else rel


def _claim(folder: str) -> None:
    """Make ``folder`` the demo's (marker file); refuse a non-empty folder the demo did not make."""
    if os.path.isdir(folder) and os.listdir(folder) and not os.path.exists(os.path.join(folder, MARKER)):
        raise UserError(f"{folder} exists and was not made by the demo; choose another folder")
    os.makedirs(folder, exist_ok=True)
    open(os.path.join(folder, MARKER), "w").close()


def _infill(argv: list) -> int:
    """Run ``inbetween infill ...argv`` in this process (its own parser: no import of the top-level CLI)."""
    from inbetween_jax.cli import infill_cmd
    parser = argparse.ArgumentParser(prog="inbetween")
    infill_cmd.add_parser(parser.add_subparsers())
    args = parser.parse_args(argv)
    return args.run(args)


def run(args) -> int:
    if args.steps < 1:
        raise UserError(f"--steps must be >= 1, got {args.steps}")
    notice = NOTICE.format(steps=args.steps)
    print(notice + "\n", flush=True)
    t0 = time.time()
    for folder in (args.runs, args.results):
        _claim(folder)
    from inbetween_jax.runner import train_model
    from inbetween_jax.train.loop import enable_compilation_cache
    try:
        enable_compilation_cache()             # a second demo skips most compilation
    except OSError:
        pass
    for model in MODELS:
        run_dir = os.path.join(args.runs, model)
        shutil.rmtree(run_dir, ignore_errors=True)
        print(f"== training {model}: tiny preset, {args.steps} steps -> {run_dir}", flush=True)
        t = time.time()
        steps = args.steps
        train_model(model, "tiny", [f"train.num_steps={steps}", f"train.ckpt_every={steps}",
                                    f"train.log_every={steps}"], "embedded", run_dir, progress=False, log=None)
        print(f"   {time.time() - t:.0f} s", flush=True)
    written = {}
    for model in MODELS:
        out = os.path.join(args.results, model)
        shutil.rmtree(out, ignore_errors=True)
        argv = infill_argv(model, os.path.join(args.runs, model), out, not args.no_gif)
        print(f"== {model}\n$ inbetween {shlex.join(argv)}", flush=True)
        t = time.time()
        rc = _infill(argv)
        if rc:
            return rc
        print(f"   {time.time() - t:.0f} s", flush=True)
        written[model] = [os.path.join(out, f) for f in sorted(os.listdir(out))]
    print("\nWritten files (BVH: open in Blender or any BVH viewer; *_sheet.png: keyframes black, generated grey):")
    for model, paths in written.items():
        print(f"  {model}:")
        for p in paths:
            print(f"    {p}")
    print(f"\nView another BVH file: inbetween preview FILE.bvh --gif --out DIR\n\n{notice}")
    print(f"demo wall time: {time.time() - t0:.0f} s")
    return 0
