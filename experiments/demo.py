"""``make demo``: tiny runs of the three models, then ``inbetween infill --preview`` on shipped BVH files.

    python experiments/demo.py [--steps 10] [--runs runs/demo] [--results results/demo] [--no-gif]

1. trains the S-CVAE, the CAE and the interaction model with their ``tiny`` presets for ``--steps`` steps on
   the embedded CMU clips into ``<runs>/<model>`` (replaced on every run);
2. runs the three ``inbetween infill`` commands (printed as shell commands) on clips of
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
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "experiments"))

ASSETS = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30")
MODELS = ("scvae", "cae", "interaction")
MARKER = ".inbetween_demo"
NOTICE = ("NOTE: the demo checkpoints are TINY and BARELY TRAINED ({steps} steps each): this is a plumbing demo\n"
          "      (train -> infill -> BVH + previews), not a quality demo -- expect poor, unnatural motion.\n"
          "      Real runs: `make train MODEL=...`, results and commands in docs/results/.")


def train_argv(model: str, run_dir: str, steps: int) -> list:
    """``experiments/train.py`` arguments of a tiny ``steps``-step run on the embedded data."""
    if model == "cae":
        return ["cae", "--source", "embedded", "--preset", "tiny", "--run-dir", run_dir,
                f"num_steps={steps}", f"ckpt_every={steps}", f"log_every={steps}"]
    return [model, "--source", "embedded", "--variant", "tiny", "--run-dir", run_dir,
            f"train.num_steps={steps}", f"train.ckpt_every={steps}", f"train.log_every={steps}"]


def infill_argv(model: str, run_dir: str, out: str, gif: bool) -> list:
    """``inbetween`` arguments of the demo's in-betweening of two walking clips (86 and 75 frames)."""
    from inbetween_jax.configs.scvae import get_config
    a, b = (_show(os.path.join(ASSETS, f)) for f in ("02_01.bvh", "02_02.bvh"))
    inputs = {
        "scvae": ["--start", f"{a}:20", "--end", f"{b}:40", "--samples", "3",
                  "--frames", str(get_config("tiny").train.trans_max)],        # the tiny preset's longest
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
        raise SystemExit(f"demo: error: {folder} exists and was not made by the demo; choose another folder")
    os.makedirs(folder, exist_ok=True)
    open(os.path.join(folder, MARKER), "w").close()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=10, help="training steps per model (default 10)")
    ap.add_argument("--runs", default=os.path.join("runs", "demo"), help="run folders go to RUNS/<model>")
    ap.add_argument("--results", default=os.path.join("results", "demo"), help="outputs go to RESULTS/<model>")
    ap.add_argument("--no-gif", action="store_true", help="contact sheets only (faster)")
    args = ap.parse_args(argv)
    notice = NOTICE.format(steps=args.steps)
    print(notice + "\n", flush=True)
    t0 = time.time()
    for folder in (args.runs, args.results):
        _claim(folder)
    from inbetween_jax.train import enable_compilation_cache
    try:
        enable_compilation_cache()             # a second `make demo` skips most compilation
    except OSError:
        pass
    import train

    from inbetween_jax.cli import main as inbetween
    for model in MODELS:
        run_dir = os.path.join(args.runs, model)
        shutil.rmtree(run_dir, ignore_errors=True)
        print(f"== training {model}: tiny preset, {args.steps} steps -> {run_dir}", flush=True)
        t = time.time()
        rc = train.main(train_argv(model, run_dir, args.steps))
        if rc:
            return rc
        print(f"   {time.time() - t:.0f} s", flush=True)
    written = {}
    for model in MODELS:
        out = os.path.join(args.results, model)
        shutil.rmtree(out, ignore_errors=True)
        argv = infill_argv(model, os.path.join(args.runs, model), out, not args.no_gif)
        print(f"== {model}\n$ inbetween {shlex.join(argv)}", flush=True)
        t = time.time()
        rc = inbetween(argv)
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


if __name__ == "__main__":
    sys.exit(main())
