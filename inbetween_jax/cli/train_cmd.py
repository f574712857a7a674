"""``inbetween train MODEL [--preset P] [--source DIR] [--run-dir DIR] [--num-processes N] [key=value ...]``.

Trains (or resumes) a registered model into a run folder (``run.json`` + ``checkpoints/``, see
:mod:`inbetween_jax.train.run`).  ``key=value`` overrides any config field (``train.num_steps=200``,
``model.latent_dim=8``); ``inbetween train MODEL --help`` lists them all with the preset's values.
"""
from __future__ import annotations

import argparse
import os
import sys

from inbetween_jax.models import MODELS, REGISTRY

EPILOG = """examples:
  inbetween train cae --preset tiny --source embedded train.num_steps=20     # a 20-step smoke run (~1 min)
  inbetween train scvae                                                       # the {default} preset (default)
  inbetween train scvae --preset paper --source $LAFAN1_DIR                   # the paper's sizes and schedule
Re-running the same command resumes from the run folder's latest checkpoint."""


def add_parser(sub) -> None:
    p = sub.add_parser("train", help="train or resume a model run",
                       description="Train (or resume) a registered model into a run folder (run.json + checkpoints/).",
                       epilog=EPILOG.format(default=REGISTRY["scvae"].default_preset),
                       formatter_class=argparse.RawDescriptionHelpFormatter, add_help=False)
    p.add_argument("-h", "--help", action="store_true", help="show this help (with MODEL: its config keys)")
    p.add_argument("model", nargs="?", metavar="MODEL", help=" | ".join(MODELS))
    p.add_argument("--preset", default=None, help=f"config preset: {_preset_help()}")
    p.add_argument("--source", default=None,
                   help="training data: a LaFAN1 or BVH folder, 'embedded', or 'cmu' (more CMU mocap from "
                        "$INBETWEEN_SHARED_DATA; default: $LAFAN1_DIR, else for scvae / cae 'cmu' when that folder "
                        "is found, else the embedded CMU clips)")
    p.add_argument("--run-dir", default=None, help="run folder (default runs/MODEL)")
    p.add_argument("--num-processes", type=int, default=1,
                   help="launch N local processes on JAX's distributed runtime (a single-machine check; on a "
                        "cluster run the command under its launcher instead)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--traceback", action="store_true", help="show the Python traceback of unexpected errors")
    p.add_argument("overrides", nargs="*", metavar="key=value", help="config overrides")
    p.set_defaults(run=run, parser=p)


def _preset_help() -> str:
    """The presets and the default one (each model's ``DEFAULT_PRESET``), as the registry says."""
    names = list(dict.fromkeys(p for spec in REGISTRY.values() for p in spec.presets))
    defaults = {spec.default_preset for spec in REGISTRY.values()}
    default = (defaults.pop() if len(defaults) == 1
               else ", ".join(f"{m}: {s.default_preset}" for m, s in REGISTRY.items()))
    return f"{' | '.join(names)} (default {default}; 'inbetween train MODEL --help' lists a model's presets)"


def model_help(model: str, preset: str | None) -> str:
    """The ``--help`` text of one model: summary, presets and every config key with its value."""
    from inbetween_jax.train.config import describe_config
    spec = REGISTRY[model]
    preset = preset or spec.default_preset
    lines = [f"usage: inbetween train {model} [--preset {'|'.join(spec.presets)}] [--source DIR] [--run-dir DIR] "
             "[--num-processes N] [key=value ...]", "", f"{model}: {spec.summary}", "",
             f"presets: {', '.join(spec.presets)} (default {spec.default_preset}); run folder default runs/{model}",
             "", f"config keys (values of the '{preset}' preset; override with key=value):"]
    lines += [f"  {line}" for line in describe_config(spec.get_config(preset))]
    return "\n".join(lines)


def _check(args) -> None:
    from inbetween_jax.errors import UserError
    if args.model not in REGISTRY:
        raise UserError(f"unknown model {args.model!r} (choose {', '.join(MODELS)})")
    spec = REGISTRY[args.model]
    if args.preset is not None and args.preset not in spec.presets:
        raise UserError(f"unknown preset {args.preset!r} for {args.model} (choose {', '.join(spec.presets)})")
    if args.source not in (None, "embedded", "cmu") and not os.path.isdir(args.source):
        raise UserError(f"--source {args.source}: no such folder")
    if args.num_processes < 1:
        raise UserError(f"--num-processes must be >= 1, got {args.num_processes}")
    from inbetween_jax.runner import build_config
    build_config(args.model, args.preset, args.overrides)           # bad keys / values fail here, before JAX


def run(args) -> int:
    if args.help or args.model is None:
        text = model_help(args.model, args.preset) if args.model in REGISTRY else args.parser.format_help()
        from inbetween_jax.cli.helptext import plain
        print(plain(text), file=sys.stdout if args.help else sys.stderr)
        return 0 if args.help else 2
    _check(args)
    if args.num_processes > 1:
        from inbetween_jax.cli import interrupt
        from inbetween_jax.train import distributed
        return distributed.launch_local(args.num_processes, _without_num_processes(sys.argv[1:]),
                                        env={interrupt.QUIET_ENV: "1"}, on_interrupt=interrupt.at_exit,
                                        report=interrupt.say)
    from inbetween_jax.train import distributed
    index, count = distributed.initialize()        # a no-op for one process; a cluster launcher is auto-detected
    from inbetween_jax.runner import train_model
    primary = index == 0
    train_model(args.model, args.preset, args.overrides, default_source(args.model, args.source), args.run_dir,
                progress=primary and not args.no_progress, log=print if primary else None,
                mesh=distributed.global_mesh() if count > 1 else None)
    return 0


CMU_DEFAULT_MODELS = ("scvae", "cae")


def default_source(model: str, source):
    """``--source`` if given, else ``$LAFAN1_DIR``; else, for the single-character models, ``cmu`` (every CMU clip
    on the embedded rig) when the shared mocap folder holds its folders, else the embedded clips (a note on stderr
    says so, and why)."""
    if source or os.environ.get("LAFAN1_DIR") or model not in CMU_DEFAULT_MODELS:
        return source
    from inbetween_jax.data.sources import cmu_unavailable
    why = cmu_unavailable()
    if why is None:
        return "cmu"
    print(f"inbetween: note: training on the embedded CMU clips instead of the cmu source: {why}", file=sys.stderr)
    return None


def _without_num_processes(argv: list) -> list:
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        if a == "--num-processes":
            skip = True
            continue
        if a.startswith("--num-processes="):
            continue
        out.append(a)
    return out
