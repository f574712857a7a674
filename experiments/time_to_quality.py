"""Time to quality: train a model's shipped recipe from scratch and report the training wall time until its
validation score first reaches the shipped weights' own.

    python experiments/time_to_quality.py MODEL [--source S] [--run-dir DIR] [--stop-at N] [key=value ...]

The recipe is the shipped ``run.json``'s preset and training overrides (``key=value`` adds to them), trained with
``inbetween``'s one training path into ``--run-dir`` (default ``runs/ttq_<MODEL>``; resumable).  The target is the
model's ``bench.val_score`` of the shipped weights, as trained (the inference-only switches set at export off), on
the same validation split (lower is better).  Every checkpoint is scored the way ``inbetween select-checkpoint``
does; every checkpoint's score and training seconds are printed, and the first one at or below the target is
reported with the training seconds up to it (``train_wall_s`` in the checkpoint, compile time included, scoring
excluded).
``--stop-at N`` ends training after step N with the full schedule (the shipped CAE was stopped at 600 of 1,600).
"""
import argparse
import json


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("model")
    p.add_argument("--source", default=None, help="data source (default: the shipped run's)")
    p.add_argument("--run-dir", default=None)
    p.add_argument("--stop-at", type=int, default=None)
    p.add_argument("overrides", nargs="*", metavar="key=value")
    a = p.parse_intermixed_args()
    from inbetween_jax import malloc, xla_cpu
    malloc.reexec()                                             # as `inbetween train MODEL` runs: its malloc
    xla_cpu.configure(a.model)                                  # and XLA:CPU settings
    from inbetween_jax.models import REGISTRY
    from inbetween_jax.runner import train_model
    from inbetween_jax.shipped import shipped_as_trained
    from inbetween_jax.train.select import checkpoint_wall_times, select_with_bench, time_to_score
    shipped = shipped_as_trained(a.model)
    source = a.source or shipped.data.get("source")
    bench = REGISTRY[a.model].module("bench")
    target = float(bench.val_score(shipped, source))          # the network as trained: no inference-only switch
    print(f"{a.model}: target {target:.4f} (the shipped weights' validation score); recipe {shipped.preset} "
          f"{' '.join(list(shipped.overrides) + a.overrides)}", flush=True)
    run_dir, _ = train_model(a.model, shipped.preset, list(shipped.overrides) + a.overrides, source,
                             a.run_dir or f"runs/ttq_{a.model}", stop_at=a.stop_at)
    selection = select_with_bench(run_dir, source, bench)
    out = time_to_score(run_dir, selection, target)
    scores = {int(k): float(v) for k, v in selection["scores"].items()}
    walls = checkpoint_wall_times(run_dir, scores)
    out["checkpoints"] = [{"step": k, "score": scores[k], "train_wall_s": walls[k]} for k in sorted(scores)]
    for row in out["checkpoints"]:
        wall = "-" if row["train_wall_s"] is None else f"{row['train_wall_s']:.0f} s"
        print(f"  step {row['step']:6d}  score {row['score']:.6f} ({row['score'] / target - 1:+.4%} of the target)"
              f"  training {wall}")
    wall = "-" if out["train_wall_s"] is None else f"{out['train_wall_s']:.0f} s"
    print(f"{a.model}: first checkpoint at or below {target:.4f}: step {out['step']} (score {out['score']}); "
          f"training wall time to it: {wall}")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
