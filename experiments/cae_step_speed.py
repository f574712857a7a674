"""Where the CAE's training step goes, and the XLA:CPU settings (docs/results/speed.md, "The CAE step").

    python experiments/cae_step_speed.py layers      # conv weight gradients: XLA's against shifted-slice matmuls
    python experiments/cae_step_speed.py grad        # the CAE loss gradient: each change on and off, one process
    python experiments/cae_step_speed.py flags [--rounds 3]   # train steps under each YNNPACK setting
    python experiments/cae_step_speed.py profile [MODEL]      # a train step's op time by XLA op kind (cae)
    python experiments/cae_step_speed.py remat [MODEL] [--reps 15]   # model.remat policies, one process (scvae-cpu)
    python experiments/cae_step_speed.py ab MODEL --try "" --try train.ema_decay=0.995   # any config changes

``layers`` times, per conv shape of the CAE (batch 16, 66 x 168 input), the weight gradient of XLA's own
autodiff against the custom VJP the model used before (kh*kw shifted-slice matmuls).  ``grad`` times the
``improved`` preset's loss gradient on one real batch with that custom VJP and the zero-dilated transposed conv
(before), XLA's gradient (1) and then the phase-split transposed conv (2, the model now).  ``flags`` runs one
fresh process per model and ``--xla_cpu_experimental_ynn_fusion_type`` setting (XLA's default, ``individual_dot``,
none), rounds in rotating order, and prints each median of 9 train steps (:mod:`inbetween_jax.xla_cpu`).
``remat`` times the S-CVAE's or the interaction model's step under each ``model.remat`` policy in one process
(:mod:`inbetween_jax.train.remat`; the CAE has no rollout); ``ab`` the same for any config changes (``--try``:
space-separated ``key=value``, the first the reference).  Medians in ms; compare ratios within one run.
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np

SETTINGS = (None, "individual_dot", "")
MODELS = ("cae", "interaction", "scvae-cpu", "scvae-paper")


def _ms(f, *args, n=9):
    import jax
    jax.block_until_ready(f(*args))
    jax.block_until_ready(f(*args))
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        jax.block_until_ready(f(*args))
        ts.append(time.perf_counter() - t)
    return 1000 * float(np.median(ts))


def slice_weight_grad(x, g, kh, kw):
    """The earlier custom VJP's weight gradient: kh*kw matmuls of shifted input slices with the output gradient."""
    import jax.numpy as jnp
    h, wd, cin = x.shape[1:]
    xp = jnp.pad(x, ((0, 0), (kh // 2, kh // 2), (kw // 2, kw // 2), (0, 0)))
    g2 = g.reshape(-1, g.shape[-1])
    return jnp.stack([jnp.stack([xp[:, i:i + h, j:j + wd, :].reshape(-1, cin).T @ g2 for j in range(kw)])
                      for i in range(kh)])


def layers():
    import jax
    from inbetween_jax.models.cae import model as cae
    shapes = [(16, 66, 168, 2, 8, 3), (16, 66, 168, 8, 8, 3), (16, 33, 84, 16, 16, 3), (16, 17, 42, 32, 32, 3),
              (16, 9, 21, 64, 64, 3), (16, 10, 22, 128, 128, 3), (16, 66, 168, 32, 32, 3), (16, 1, 168, 132, 256, 25)]
    print("| x (B, H, W, Cin) -> Cout, kernel | shifted slices | XLA's own | ratio |\n|---|---|---|---|")
    for b, h, w, ci, co, k in shapes:
        kh, kw = (3, 3) if k == 3 else (1, k)
        x = jax.random.normal(jax.random.key(0), (b, h, w, ci))
        g = jax.random.normal(jax.random.key(1), (b, h, w, co))
        w0 = jax.numpy.zeros((kh, kw, ci, co))
        own = jax.jit(lambda x, g: jax.vjp(lambda w: cae.conv_same(x, w), w0)[1](g)[0])
        old = jax.jit(lambda x, g: slice_weight_grad(x, g, kh, kw))
        ref = np.asarray(old(x, g))
        assert np.abs(np.asarray(own(x, g)) - ref).max() <= 1e-4 * np.abs(ref).max()    # float32 sums of 1e5 terms
        a, o = _ms(old, x, g), _ms(own, x, g)
        print(f"| ({b}, {h}, {w}, {ci}) -> {co}, {kh}x{kw} | {a:.1f} | {o:.1f} | {a / o:.2f}x |", flush=True)


def grad():
    import jax
    import jax.numpy as jnp
    from inbetween_jax.models.cae import model as cae
    from inbetween_jax.models.cae import train as cae_train
    from inbetween_jax.models.cae.config import get_config
    from inbetween_jax.models.cae.losses import weighted_l1
    cfg = get_config("improved")
    tr = cae_train.make_training(cfg, cae_train.load_data(cfg, None, "train"))
    x = jnp.asarray(tr.batch_fn(cfg.train.num_steps // 2, jax.random.key(2))["x"])
    params = tr.init_fn(jax.random.key(0))["params"]
    params = jax.tree.map(lambda a: a + 0.01 * jax.random.normal(jax.random.key(5), a.shape), params)
    mask = (jax.random.uniform(jax.random.key(3), x.shape) > 0.3).astype(jnp.float32)

    conv_same, conv_upsampled = cae.conv_same, cae.conv_upsampled

    @jax.custom_vjp
    def slice_conv(x, w):
        return conv_same(x, w)

    slice_conv.defvjp(lambda x, w: (conv_same(x, w), (x, w)),
                      lambda res, g: (jax.linear_transpose(lambda x_: conv_same(x_, res[1]), res[0])(g)[0],
                                      slice_weight_grad(res[0], g, *res[1].shape[:2])))
    zero_dilated = lambda z, w, up_h=True: cae.conv_same(cae.upsample_zeros(z, up_h), w)    # noqa: E731
    variants = {"before: shifted-slice weight gradient, zero-dilated transposed conv": (slice_conv, zero_dilated),
                "1: XLA's weight gradient": (conv_same, zero_dilated),
                "2: + phase-split transposed conv (the model now)": (conv_same, conv_upsampled)}
    loss = lambda p, xm, m: weighted_l1(cae.apply(p, xm, cfg, m), x, m, 4.0)            # noqa: E731
    times, values = {}, {}
    try:
        for _ in range(2):                                  # two rounds, rotating, the faster kept
            for name, (conv, up) in variants.items():
                cae.conv_same, cae.conv_upsampled = conv, up
                f = jax.jit(jax.value_and_grad(loss))
                values[name] = float(f(params, x * mask, mask)[0])
                times[name] = min(times.get(name, np.inf), _ms(f, params, x * mask, mask))
    finally:
        cae.conv_same, cae.conv_upsampled = conv_same, conv_upsampled
    base = times[next(iter(variants))]
    print("| CAE `improved` loss gradient, batch 16 x 66 x 168 | ms | speed-up | loss |\n|---|---|---|---|")
    for name in variants:
        print(f"| {name} | {times[name]:.1f} | {base / times[name]:.2f}x | {values[name]:.7f} |")


def step_call(model: str, overrides=()):
    """One train step of ``model`` as a callable (cae: ``improved``; interaction: ``improved`` with 3 members;
    scvae-cpu / scvae-paper: the speed section's S-CVAE step, batch 32, 50 frames) on one real batch; each call
    advances the state, waits for the step and returns its metrics.  ``overrides``: ``key=value`` config changes."""
    import jax
    from inbetween_jax.train.config import apply_overrides
    from inbetween_jax.train.loop import make_step_fn, strongly_typed
    if model.startswith("scvae"):
        from inbetween_jax.data import load_dataset
        from inbetween_jax.evaluation.speed import scvae_step_setup
        from inbetween_jax.models.scvae.features import TrainData, compute_stats
        win = load_dataset(None, "benchmark")
        _, batch, step_fn, init, _ = scvae_step_setup(model.split("-")[1], TrainData.from_windows(win),
                                                      compute_stats(win), overrides=overrides)
    else:
        if model == "interaction":
            from inbetween_jax.models.interaction import train as T
            from inbetween_jax.models.interaction.config import get_config
            cfg = apply_overrides(get_config("improved"), ["model.members=3", *overrides])
        else:
            from inbetween_jax.models.cae import train as T
            from inbetween_jax.models.cae.config import get_config
            cfg = apply_overrides(get_config("improved"), list(overrides))
        tr = T.make_training(cfg, T.load_data(cfg, None, "train"))
        batch, init, step_fn = tr.batch_fn(tr.num_steps // 2, jax.random.key(2)), tr.init_fn, tr.step_fn
    batch = jax.tree.map(jax.numpy.asarray, batch)
    state = {"s": jax.tree.map(strongly_typed, init(jax.random.key(0)))}
    step = make_step_fn(step_fn, jax.random.key(1))

    def one():
        state["s"], m = step(state["s"], batch, np.int32(0))
        return jax.block_until_ready(m)
    one.hlo = lambda: step.lower(state["s"], batch, np.int32(0)).compile().as_text()     # the optimised program
    return one


def entry_copies(hlo: str) -> tuple:
    """(count, MB) of the ``copy`` instructions in the optimised program's entry computation (outside every loop
    body: they run once per step)."""
    import re
    entry, n, size = False, 0, 0
    for line in hlo.splitlines():
        if line and not line.startswith(" ") and line.rstrip().endswith("{"):
            entry = line.startswith("ENTRY")
        m = re.search(r"= (\w+)\[([\d,]*)\]\S* copy\(", line) if entry else None
        if m:
            n += 1
            size += int(np.prod([int(d) for d in m.group(2).split(",") if d])) * (1 if m.group(1) == "pred" else 4)
    return n, size / 1e6


def remat(model: str, reps: int):
    """``model.remat`` A/B in one process (:func:`compare`), one step function per policy
    (:mod:`inbetween_jax.train.remat`), keeping everything the reference."""
    from inbetween_jax.train.remat import REMAT_POLICIES
    compare(model, {p or "(empty): keep all": [f"model.remat={p}"] for p in REMAT_POLICIES}, reps, "`model.remat`")


def compare(model: str, variants: dict, reps: int, what: str = "config"):
    """A/B in one process: one step function per variant (``{name: [key=value, ...]}``, the first the
    reference), the same first state and batch; the calls interleaved (order reversed every round), medians of wall
    and CPU time (``time.process_time``: both threads' work, less moved by other jobs than the wall time), and the
    first step's loss of each (the same maths: equal to float tolerance)."""
    import jax
    policies = list(variants)
    calls, loss = {}, {}
    for p in policies:
        calls[p] = step_call(model, variants[p])
        m = calls[p]()
        loss[p] = float(jax.device_get(m["loss"]))
        calls[p]()
    wall, cpu = {p: [] for p in policies}, {p: [] for p in policies}
    for r in range(reps):
        for p in policies if r % 2 == 0 else policies[::-1]:
            t, c = time.perf_counter(), time.process_time()
            calls[p]()
            wall[p].append(1000 * (time.perf_counter() - t))
            cpu[p].append(1000 * (time.process_time() - c))
    w0, c0 = np.median(wall[policies[0]]), np.median(cpu[policies[0]])
    print(f"| {model}, {what} ({reps} calls each) | wall ms | x the first | CPU ms | x the first | first loss "
          "| copies once per step |")
    print("|---|---|---|---|---|---|---|")
    for p in policies:
        w, c = np.median(wall[p]), np.median(cpu[p])
        n, mb = entry_copies(calls[p].hlo())
        print(f"| `{p}` | {w:.1f} | {w / w0:.3f} | {c:.1f} | {c / c0:.3f} | {loss[p]:.7f} "
              f"| {n}, {mb:.1f} MB |", flush=True)


def step_ms(model: str) -> float:
    """Median of 9 train steps of ``model`` (:func:`step_call`) in this process."""
    return _ms(step_call(model))


def flags(rounds: int):
    env0 = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "INBETWEEN_XLA_DEFAULTS")}
    out = {}
    for r in range(rounds):
        for i in range(len(SETTINGS)):
            setting = SETTINGS[(i + r) % len(SETTINGS)]
            env = dict(env0)
            if setting is not None:
                env["XLA_FLAGS"] = f"--xla_cpu_experimental_ynn_fusion_type={setting}"
            for model in MODELS:
                res = subprocess.run([sys.executable, __file__, "step", model], env=env, capture_output=True,
                                     text=True)
                ms = float(res.stdout.strip().splitlines()[-1])
                out.setdefault(model, {}).setdefault(setting, []).append(ms)
                print(f"round {r + 1}, {model}, {setting!r}: {ms:.1f} ms", flush=True)
    names = {None: "XLA's default", "individual_dot": "`individual_dot`", "": "none (empty)"}
    print("\n| train step (ms, median of 9; per process) | " + " | ".join(names[s] for s in SETTINGS) + " |")
    print("|---|" + "---|" * len(SETTINGS))
    for model, per in out.items():
        print(f"| {model} | " + " | ".join(f"{min(per[s]):.0f}-{max(per[s]):.0f}" for s in SETTINGS) + " |")


def profile(model: str, calls: int = 5):
    """The op time of ``model``'s train step by XLA op kind (:func:`inbetween_jax.profiling.op_ms_by_kind`), then
    the median step without the profiler in the same process."""
    from inbetween_jax.profiling import op_ms_by_kind
    one = step_call(model)
    wall, kinds, covered = op_ms_by_kind(one, calls)
    total = sum(kinds.values())
    print(f"{model}: {wall:.1f} ms per step under the profiler, {total:.1f} ms of traced op time, some op running "
          f"during {covered:.1f} ms; without the profiler {_ms(one):.1f} ms (median of 9)")
    print("| op kind | ms per step | share of op time |\n|---|---|---|")
    for name, ms in kinds.items():
        if ms >= 0.01 * total:
            print(f"| `{name}` | {ms:.2f} | {100 * ms / total:.1f} % |")


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=("layers", "grad", "flags", "step", "profile", "remat", "ab"))
    p.add_argument("model", nargs="?", choices=MODELS)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--reps", type=int, default=15, help="remat, ab: timed calls per variant")
    p.add_argument("--try", dest="tries", action="append", default=[], help="ab: a variant's key=value changes")
    a = p.parse_args()
    if a.what == "step":
        print(f"{step_ms(a.model):.3f}")
    elif a.what == "remat":
        model = a.model or "scvae-cpu"
        if model == "cae":
            p.error("remat: the CAE has no rollout; choose interaction, scvae-cpu or scvae-paper")
        from inbetween_jax import xla_cpu
        xla_cpu.configure(model.split("-")[0])
        remat(model, a.reps)
    elif a.what == "ab":
        from inbetween_jax import xla_cpu
        xla_cpu.configure((a.model or "cae").split("-")[0])
        compare(a.model or "cae", {t or "(as preset)": t.split() for t in a.tries}, a.reps)
    elif a.what == "profile":
        from inbetween_jax import xla_cpu
        xla_cpu.configure((a.model or "cae").split("-")[0])          # as `inbetween` runs the model
        profile(a.model or "cae")
    else:
        {"layers": layers, "grad": grad, "flags": lambda: flags(a.rounds)}[a.what]()
