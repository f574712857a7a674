"""Run-to-run spread of the S-CVAE train step's median and its share of the matmul peak, one fresh process per run.

    python experiments/step_spread.py [--runs 5] [--reps 7] [--width paper]

Each run is a new Python process (as a new training or bench run would be) that sets XLA:CPU as ``inbetween``
does for the S-CVAE (:mod:`inbetween_jax.xla_cpu`), measures the float32 matmul peak, then times the speed
section's training step (:func:`inbetween_jax.evaluation.speed._train_step_row`: batch 32, a 50-frame
transition) and prints its median, the calls, GFLOP/s and % of that peak; the runs share one persistent compile
cache.  Last line: max / min of the medians.  Time it on an otherwise idle machine: another busy process on one of
the 2 cores doubles the step (docs/results/speed.md).
"""
import argparse
import json
import subprocess
import sys
import tempfile


def child(width: str, reps: int, cache: str) -> None:
    from inbetween_jax import xla_cpu
    xla_cpu.configure("scvae")
    from inbetween_jax.data import load_dataset
    from inbetween_jax.evaluation import speed
    from inbetween_jax.models.scvae.features import TrainData, compute_stats
    from inbetween_jax.profiling import matmul_peak_flops
    from inbetween_jax.train.loop import enable_compilation_cache
    enable_compilation_cache(cache)
    win = load_dataset(None, "benchmark")
    peak = matmul_peak_flops() / 1e9
    out, _, _ = speed._train_step_row(width, win, TrainData.from_windows(win), compute_stats(win), reps, None)
    print(json.dumps({"step_ms": out["jax_step_ms"], "calls_ms": out["calls_ms"]["jax"],
                      "step_gflop": out["step_gflop"], "gflops": out["jax_gflops"], "peak_gflops": peak}))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--reps", type=int, default=7)
    p.add_argument("--width", default="paper")
    p.add_argument("--child", default=None, help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.child:
        return child(a.width, a.reps, a.child)
    medians = []
    with tempfile.TemporaryDirectory() as cache:
        for i in range(a.runs):
            cmd = [sys.executable, __file__, "--child", cache, "--width", a.width, "--reps", str(a.reps)]
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1]
            r = json.loads(out)
            medians.append(r["step_ms"])
            calls = f"{min(r['calls_ms']):.0f}-{max(r['calls_ms']):.0f}"
            print(f"run {i + 1}: median {r['step_ms']:.0f} ms (calls {calls}), "
                  f"{r['gflops']:.1f} GFLOP/s of {r['step_gflop']:.1f} GFLOP per step, peak {r['peak_gflops']:.1f}: "
                  f"{100 * r['gflops'] / r['peak_gflops']:.0f} % of peak", flush=True)
    print(f"spread of the medians (max / min over {a.runs} runs): {max(medians) / min(medians):.3f}")


if __name__ == "__main__":
    main()
