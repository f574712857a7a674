"""Steps/s of 1 process vs 2 local processes (1 CPU device each) training on the same global batch.

``python -m experiments.scaling [--steps 30] [--batch 256]`` from the repository root.  Model: MLP
(first + last frame -> middle frame rotations of real embedded CMU windows), Adam; after 3 warm-up
steps ``--steps`` data-parallel steps are timed, each blocked on its result.
"""
import json, os, sys, tempfile, time
import numpy as np


def worker(out, steps, batch, hidden=512, gap=10):
    from inbetween_jax.train import distributed
    distributed.initialize()                                                   # before any JAX computation
    import jax, jax.numpy as jnp, optax
    from inbetween_jax.data import load_dataset
    from inbetween_jax.train import make_mesh, make_parallel_step_fn, replicate
    q = np.asarray(load_dataset("embedded", "train").local_quats)            # (N, T, J, 4)
    d, opt = q.shape[2] * 4, optax.adam(1e-3)
    k1, k2 = jax.random.split(jax.random.key(0))
    params = {"w1": 0.05 * jax.random.normal(k1, (2 * d, hidden)), "w2": 0.05 * jax.random.normal(k2, (hidden, d))}

    def step(state, b, key):
        loss_fn = lambda p: jnp.mean((jnp.tanh(b["x"] @ p["w1"]) @ p["w2"] - b["y"]) ** 2)
        loss, g = jax.value_and_grad(loss_fn)(state[0])
        upd, o = opt.update(g, state[1], state[0])
        return (optax.apply_updates(state[0], upd), o), {"loss": loss}

    def batch_fn(i):
        r = np.random.default_rng(i)
        w, t = r.integers(0, q.shape[0], batch), r.integers(0, q.shape[1] - gap, batch)
        return {"x": np.concatenate([q[w, t].reshape(batch, -1), q[w, t + gap].reshape(batch, -1)], 1),
                "y": q[w, t + gap // 2].reshape(batch, -1)}

    mesh = make_mesh()
    state, fn = replicate((params, opt.init(params)), mesh), make_parallel_step_fn(step, jax.random.key(1), mesh)
    for i in range(3 + steps):
        if i == 3:                                                             # after compile + warm-up
            t0 = time.perf_counter()
        state, m = jax.block_until_ready(fn(state, batch_fn(i), np.int32(i)))
    if jax.process_index() == 0:
        with open(out, "w") as f:
            json.dump({"steps_per_s": steps / (time.perf_counter() - t0)}, f)


if __name__ == "__main__":
    args = dict(zip(sys.argv[1::2], sys.argv[2::2]))
    if "--worker" in args:
        worker(args["--worker"], int(args["--steps"]), int(args["--batch"]))
        sys.exit(0)
    from inbetween_jax.train.distributed import launch_local
    steps, batch, res = args.get("--steps", "30"), args.get("--batch", "256"), {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in (1, 2):
            out = os.path.join(tmp, f"{n}.json")
            if rc := launch_local(n, ["--worker", out, "--steps", steps, "--batch", batch],
                                  module="experiments.scaling", env={"JAX_PLATFORMS": "cpu", "XLA_FLAGS": ""}):
                sys.exit(rc)
            res[n] = json.load(open(out))["steps_per_s"]
            print(f"{n} process(es), global batch {batch}: {res[n]:.1f} steps/s")
    print(f"ratio 2 processes / 1 process: {res[2] / res[1]:.2f} (CPU cores here: {os.cpu_count()})")
