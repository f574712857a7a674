"""The interaction training step before and after its two speed changes, side by side in one process.

    python experiments/interaction_step_speed.py [--members 3] [--rounds 3] [--reps 5]

Variants of the shipped recipe's step (``improved``, ``data.tta_guess=0.5``, ``model.members`` M, one real batch
of the fit takes): the members as one ``vmap`` (as before) or as M independent subgraphs (the package's step), and
the ConvGCN's 1D convolutions as XLA convolutions (``nnx.Conv``, as before) or as one matmul with the kernel's
banded matrix (:func:`inbetween_jax.models.interaction.layers.conv_same`, the package's).  Prints each variant's
losses after 3 steps from the same state (the same maths: equal to float tolerance) and its median step time
over ``rounds`` x ``reps`` calls, the rounds interleaved.  Time it on an otherwise idle machine.
"""
import argparse

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--members", type=int, default=3)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--reps", type=int, default=5)
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    a = p.parse_args()
    from inbetween_jax import xla_cpu
    xla_cpu.configure("interaction")
    import jax
    from inbetween_jax.models.interaction import layers
    from inbetween_jax.models.interaction import train as it
    from inbetween_jax.profiling import median_ms, time_calls
    from inbetween_jax.runner import build_config
    from inbetween_jax.train.loop import enable_compilation_cache, make_step_fn, strongly_typed
    enable_compilation_cache()
    M, banded = a.members, layers.conv_same
    overrides = [f"model.members={M}", "data.tta_guess=0.5"]
    cfg = build_config("interaction", "improved", overrides)
    one_cfg = build_config("interaction", "improved", ["model.members=1", "data.tta_guess=0.5"])
    data = it.load_data(cfg, a.source, "fit")
    ensemble, single = it.make_training(cfg, data), it.make_training(one_cfg, data)

    def vmapped(state, batch, key):             # the step as it was: one vmap over the members
        new, metrics = jax.vmap(single.step_fn, in_axes=({"params": 0, "opt": 0, "step": None}, 0, 0))(
            state, batch, jax.random.split(key, M))
        return dict(new, step=state["step"] + 1), jax.tree.map(lambda v: v.mean(0), metrics)
    state0 = jax.tree.map(strongly_typed, ensemble.init_fn(jax.random.key(0)))
    batch = jax.tree.map(jax.numpy.asarray, ensemble.batch_fn(0, jax.random.key(1)))
    variants = {"vmap, XLA conv (before)": (vmapped, False), "subgraphs, XLA conv": (ensemble.step_fn, False),
                "vmap, banded conv": (vmapped, True), "subgraphs, banded conv (now)": (ensemble.step_fn, True)}
    steps = {}
    for name, (fn, use_band) in variants.items():
        layers.conv_same = banded if use_band else (lambda conv, x: conv(x))       # read when the step is traced
        step, s = make_step_fn(fn, jax.random.key(1)), jax.tree.map(lambda v: v.copy(), state0)   # donated
        for i in range(3):
            s, m = step(s, batch, np.int32(i))
        print(f"{name}: after 3 steps " + ", ".join(f"{k} {float(v):.7f}" for k, v in sorted(m.items())), flush=True)
        steps[name] = (step, {"s": s})
    layers.conv_same = banded
    times = {n: [] for n in steps}
    for _ in range(a.rounds):
        for name, (step, held) in steps.items():
            def run(step=step, held=held):
                held["s"], m = step(held["s"], batch, np.int32(0))
                return m
            times[name] += time_calls(run, reps=a.reps)
    base = median_ms(times["vmap, XLA conv (before)"])
    print(f"| interaction step, {M} members, batch {cfg.train.batch_size} | median ms | speed-up |\n|---|---|---|")
    for name in steps:
        print(f"| {name} | {median_ms(times[name]):.1f} | {base / median_ms(times[name]):.2f}x |")


if __name__ == "__main__":
    main()
