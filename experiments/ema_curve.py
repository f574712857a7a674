"""Every checkpoint of a run trained with the parameters' moving average (``train.ema_decay``), scored on the
validation split both ways: the average (what inference uses) and the last parameters (``train.ema_eval=false``),
with the training wall time up to each checkpoint and the shipped weights' own score as the target
(``experiments/time_to_quality.py``'s).  Validation data only.

    python experiments/ema_curve.py RUN_DIR [--source S]
"""
import argparse
import dataclasses


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--source", default=None)
    a = p.parse_args()
    from inbetween_jax import malloc, xla_cpu
    from inbetween_jax.train.run import _checkpoint_steps, load_run
    run = load_run(a.run_dir, need_checkpoint=False)
    malloc.reexec()
    xla_cpu.configure(run.model)
    import os
    from inbetween_jax.models import REGISTRY
    from inbetween_jax.shipped import shipped_as_trained
    from inbetween_jax.train.select import checkpoint_wall_times
    bench = REGISTRY[run.model].module("bench")
    source = a.source or run.data.get("source")
    target = float(bench.val_score(shipped_as_trained(run.model), source))
    steps = [s for s in _checkpoint_steps(os.path.join(a.run_dir, "checkpoints")) if s > 0]
    walls = checkpoint_wall_times(a.run_dir, steps)
    print(f"{run.model}: target {target:.4f} (the shipped weights' validation score); train.ema_decay "
          f"{run.config['train'].get('ema_decay', 0.0)}")
    print("| step | training wall | last parameters | moving average | average / last |")
    print("|---|---|---|---|---|")
    for step in steps:
        avg_run = load_run(a.run_dir, step)
        raw_run = dataclasses.replace(avg_run, config={**avg_run.config,
                                                       "train": {**avg_run.config["train"], "ema_eval": False}})
        raw, avg = float(bench.val_score(raw_run, source)), float(bench.val_score(avg_run, source))
        wall = "-" if walls.get(step) is None else f"{walls[step]:.0f} s"
        mark = lambda v: f"**{v:.4f}**" if v <= target else f"{v:.4f}"     # noqa: E731
        print(f"| {step} | {wall} | {mark(raw)} | {mark(avg)} | {avg / raw:.4f} |", flush=True)


if __name__ == "__main__":
    main()
