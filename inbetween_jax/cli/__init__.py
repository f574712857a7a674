"""``inbetween``: the one console script.

    inbetween train MODEL [--preset P] [--source DIR] [--run-dir DIR] [key=value ...]   train / resume a run
    inbetween bench [--source DIR] [--runs DIR] [--results DIR]                           benchmark tables
    inbetween infill --model MODEL [--ckpt RUN] ... --out DIR [--preview] [--gif]         in-between BVH files
    inbetween preview FILE.bvh [--frames a:b] [--gif] [--out DIR]                         draw a BVH file
    inbetween demo                                                                        tiny end-to-end demo
    inbetween speed [--results DIR]                                                       JAX / PyTorch speed
    inbetween sweep [--rows full,no_d,...] [--seeds N] [--steps N] [key=value ...]        ablations x seeds
    inbetween select-checkpoint RUN_DIR [--source S]                                      choose a run's step (validation)
    inbetween calibrate-gate RUN_DIR [--source S]                                         a run's out-of-distribution gate
    inbetween build-bank RUN_DIR [--split fit] [--mirror] [--set KEY=VALUE ...]           a run's motion bank
    inbetween ship-weights RUN_DIR [--step N] [--dtype float16|float32] [--why TEXT]      ship a run's weights

Arguments and input files are checked before JAX is imported, so mistakes are reported at once.  Problems with
the inputs print one line ``inbetween: error: ...`` and exit with status 2; a bug prints one line with status 1
(``--traceback`` shows it); Ctrl-C prints one line and exits with status 130, leaving nothing half-written.
"""
from __future__ import annotations

import argparse
import os
import sys

from inbetween_jax.errors import UserError

__all__ = ["main", "entry", "build_parser"]


class ArgError(Exception):
    pass


class Parser(argparse.ArgumentParser):
    def error(self, message):                     # one line instead of usage + message, status 2
        raise ArgError(f"{self.prog}: {message}")


def build_parser() -> argparse.ArgumentParser:
    from inbetween_jax.cli import (bench_cmd, demo_cmd, infill_cmd, run_tools_cmd, ship_weights_cmd, speed_cmd,
                                   sweep_cmd, train_cmd)
    from inbetween_jax.cli.helptext import plain_help
    ap = Parser(prog="inbetween", description=__doc__.split("\n\n")[0].split(": ", 1)[1],
                formatter_class=argparse.RawDescriptionHelpFormatter,
                epilog="\n".join(__doc__.split("\n\n")[1].splitlines()) + "\n\n'inbetween COMMAND --help' for each.")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for module in (train_cmd, bench_cmd, infill_cmd, demo_cmd, speed_cmd, sweep_cmd, run_tools_cmd, ship_weights_cmd):
        module.add_parser(sub)
    plain_help(ap)                                # the texts come from docstrings: no Sphinx markup
    return ap


def _one_line(msg: str) -> str:
    return "; ".join(s.strip() for s in str(msg).splitlines() if s.strip()) or "unknown problem"


def fail(msg: str) -> int:
    from inbetween_jax.cli import interrupt
    interrupt.say(f"inbetween: error: {_one_line(msg)}")
    return 2


def main(argv=None) -> int:
    """Run the ``inbetween`` command line ``argv`` (default ``sys.argv[1:]``); returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args, extra = build_parser().parse_known_args(argv)
        if extra and hasattr(args, "overrides"):     # key=value overrides after options (train, sweep)
            is_override = ["=" in a and not a.startswith("-") for a in extra]
            args.overrides = list(args.overrides) + [a for a, o in zip(extra, is_override) if o]
            extra = [a for a, o in zip(extra, is_override) if not o]
        if extra:
            raise ArgError(f"inbetween {args.command or ''}: unrecognized arguments: {' '.join(extra)}".replace("  ", " "))
    except ArgError as e:
        return fail(str(e))
    except SystemExit as e:                       # --help
        return e.code if isinstance(e.code, int) else 0
    if args.command is None:
        build_parser().print_help(sys.stderr)
        return 2
    traceback = getattr(args, "traceback", False)
    try:
        return args.run(args)
    except (UserError, ValueError, OSError, FloatingPointError) as e:   # BVHError, ConfigError, RunError: ValueError
        if traceback:
            raise
        return fail(str(e))
    except Exception as e:                        # a bug, not the user's fault: one line unless --traceback
        if traceback:
            raise
        from inbetween_jax.cli import interrupt
        interrupt.say(f"inbetween: internal error: {type(e).__name__}: {_one_line(str(e))} (rerun with --traceback)")
        return 1


def entry() -> None:
    """Console-script entry point: a faster malloc where the machine has one (:mod:`inbetween_jax.malloc`; the
    command restarts once under it), the measured XLA:CPU settings (:mod:`inbetween_jax.xla_cpu`), prompt Ctrl-C
    handling, then :func:`main`."""
    from inbetween_jax import malloc, xla_cpu
    malloc.reexec()
    from inbetween_jax.cli import interrupt
    xla_cpu.configure(xla_cpu.model_in_argv(sys.argv[1:]))
    quiet = bool(os.environ.get(interrupt.QUIET_ENV))
    interrupt.install(None if quiet else "interrupted")
    try:
        code = main()
    except KeyboardInterrupt:
        if not quiet:
            print("inbetween: interrupted", file=sys.stderr)
        code = 130
    interrupt.settle()
    sys.exit(code)


if __name__ == "__main__":
    entry()
