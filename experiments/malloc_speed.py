"""Training steps under each malloc: glibc's, glibc with one arena that keeps its pages, tcmalloc and jemalloc
(docs/results/speed.md, "malloc"; :mod:`inbetween_jax.malloc`).

    python experiments/malloc_speed.py [--models cae,interaction,scvae-cpu,scvae-paper] [--rounds 3] [--steps 9]
                                       [--conds glibc,glibc_one_arena,tcmalloc,jemalloc]
    python experiments/malloc_speed.py --models torch-cae,torch-scvae-cpu --conds glibc,jemalloc   # against PyTorch

One fresh process per model, condition and round (conditions in rotating order), each timing ``--steps`` train
steps after two warm-up steps (``experiments/cae_step_speed.py``'s steps).  Per step: wall ms, minor page faults,
user and system CPU ms (``getrusage``).  The table gives, per model and condition, the median over rounds of each
process's median, and the speed-up over glibc as the median of the per-round ratios.  tcmalloc and jemalloc run
exactly as ``inbetween`` preloads them (:data:`inbetween_jax.malloc.LIBRARIES`, found by
:func:`inbetween_jax.malloc.find`); a condition whose library is not installed is skipped (Debian: ``apt-get
install libtcmalloc-minimal4 libjemalloc2``).
``torch-cae`` / ``torch-scvae-cpu`` run the speed section's rows instead (JAX, PyTorch eager and inductor on one
batch, medians of ``--steps`` calls; needs ``pip install "inbetween_jax[bench]"``): the malloc is the process's,
so PyTorch runs under it too.
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

from inbetween_jax import malloc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
CONDITIONS = {"glibc": {},
              "glibc_one_arena": {"MALLOC_ARENA_MAX": "1", "MALLOC_MMAP_MAX_": "0",     # and its pages kept
                                  "MALLOC_TRIM_THRESHOLD_": str(1 << 40), "MALLOC_TOP_PAD_": str(1 << 28)},
              "tcmalloc": malloc.LIBRARIES[0],            # (library, its environment) as inbetween preloads it
              "jemalloc": malloc.LIBRARIES[1]}


def torch_child(model: str, steps: int) -> None:
    """The speed section's rows (JAX, PyTorch eager and inductor on the same batch, one process): the CAE
    ``improved`` step or the S-CVAE cpu-width step.  Prints [jax, eager, compiled] ms."""
    from inbetween_jax import xla_cpu
    from inbetween_jax.evaluation import speed
    from inbetween_jax.evaluation.torch_ref import cae as torch_cae, scvae as torch_scvae
    xla_cpu.configure(model.split("-")[1])
    if model == "torch-cae":
        row = speed.cae_train_rows(None, steps, ("improved",), torch_cae)["improved"]
    else:
        from inbetween_jax.data import load_dataset
        from inbetween_jax.models.scvae.features import TrainData, compute_stats
        win = load_dataset(None, "benchmark")
        row = speed._train_step_row("cpu", win, TrainData.from_windows(win), compute_stats(win), steps, torch_scvae)[0]
    print(json.dumps([row.get(f"{k}_step_ms", float("nan")) for k in ("jax", "torch", "torch_compile")]))


def child(model: str, steps: int) -> None:
    if model.startswith("torch-"):
        return torch_child(model, steps)
    from cae_step_speed import step_call
    from inbetween_jax import xla_cpu
    xla_cpu.configure(model.split("-")[0])                       # as `inbetween train MODEL` runs
    one = step_call(model)
    one(), one()
    rows = []
    for _ in range(steps):
        r0, t0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
        one()
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        rows.append([(time.perf_counter() - t0) * 1e3, r1.ru_minflt - r0.ru_minflt,
                     (r1.ru_utime - r0.ru_utime) * 1e3, (r1.ru_stime - r0.ru_stime) * 1e3])
    print(json.dumps(np.median(np.array(rows), 0).tolist()))


def condition_env(name: str):
    """The environment of a condition, or None when its library is not installed."""
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "XLA_FLAGS", "MALLOC_CONF")}
    env[malloc.OPT_OUT_ENV] = "system"                  # the children never restart themselves
    cond = CONDITIONS[name]
    if isinstance(cond, dict):
        return {**env, **cond}
    found = malloc.find(libraries=(cond,))
    return None if found is None else {**env, **found[1], "LD_PRELOAD": found[0]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--models", default="cae,interaction,scvae-cpu,scvae-paper")
    p.add_argument("--conds", default=",".join(CONDITIONS))
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--steps", type=int, default=9)
    p.add_argument("--child", nargs=2, metavar=("MODEL", "STEPS"), help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.child:
        return child(a.child[0], int(a.child[1]))
    envs = {c: condition_env(c) for c in a.conds.split(",")}
    conds = [c for c, e in envs.items() if e is not None]
    res = {}
    for r in range(a.rounds):
        for model in a.models.split(","):
            for c in conds[r % len(conds):] + conds[:r % len(conds)]:
                out = subprocess.run([sys.executable, __file__, "--child", model, str(a.steps)], env=envs[c],
                                     capture_output=True, text=True)
                if out.returncode:
                    raise SystemExit(f"{model} under {c}: {out.stderr.strip().splitlines()[-1:]}")
                res.setdefault(model, {}).setdefault(c, []).append(json.loads(out.stdout.strip().splitlines()[-1]))
                print(f"round {r + 1} {model} {c}: " + ", ".join(f"{v:.1f}" for v in res[model][c][-1]), flush=True)
    steps = {m: per for m, per in res.items() if not m.startswith("torch-")}
    if steps:
        print("\n| train step | malloc | ms (median; min-max of rounds) | speed-up over glibc | page faults | "
              "user + system CPU ms |\n|---|---|---|---|---|---|")
    for model, per in steps.items():
        base = np.array([x[0] for x in per["glibc"]]) if "glibc" in per else None
        for c in conds:
            x = np.array(per[c])
            up = np.median(base / x[:, 0]) if base is not None else float("nan")
            print(f"| {model} | {c} | {np.median(x[:, 0]):.0f} ({x[:, 0].min():.0f}-{x[:, 0].max():.0f}) | "
                  f"{up:.2f}x | {np.median(x[:, 1]):.0f} | {np.median(x[:, 2]):.0f} + {np.median(x[:, 3]):.0f} |")
    torch_rows = {m: per for m, per in res.items() if m.startswith("torch-")}
    if torch_rows:
        print("\n| train step (the speed section's rows) | malloc | JAX ms | PyTorch eager ms | inductor ms | "
              "eager / JAX | inductor / JAX |\n|---|---|---|---|---|---|---|")
        for model, per in torch_rows.items():
            for c in conds:
                x = np.median(np.array(per[c]), 0)
                print(f"| {model[6:]} | {c} | {x[0]:.0f} | {x[1]:.0f} | {x[2]:.0f} | {x[1] / x[0]:.2f}x | "
                      f"{x[2] / x[0]:.2f}x |")


if __name__ == "__main__":
    main()
