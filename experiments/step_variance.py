"""Run-to-run variance of the JAX S-CVAE paper-width train step (the speed section's step: batch 32, L = 51).

``python experiments/step_variance.py [--reps N] [--rounds R] [--width paper]``: runs the step in a fresh process
per condition (allocator via LD_PRELOAD, malloc tuning, XLA_FLAGS; ``--conds a,b`` picks some), R rounds in
rotating order, and prints per call: ms, minor page faults, voluntary / involuntary context switches, user /
system CPU ms.  One shared persistent compile cache (a temp folder).  Allocators: Debian's libjemalloc2 and
libtcmalloc-minimal4 (conditions whose library is missing are skipped).
"""
import ctypes.util, dataclasses, json, os, resource, subprocess, sys, tempfile, time  # noqa: E401

JE, TC = "libjemalloc.so.2", "libtcmalloc_minimal.so.4"     # sonames: ld.so finds them on its own path
CONDITIONS = {"baseline": {},
              "jemalloc": {"LD_PRELOAD": JE},
              "tcmalloc": {"LD_PRELOAD": TC},
              "jemalloc_keep": {"LD_PRELOAD": JE,
                                "MALLOC_CONF": "dirty_decay_ms:-1,muzzy_decay_ms:-1"},
              "glibc_no_mmap": {"MALLOC_MMAP_MAX_": "0", "MALLOC_TRIM_THRESHOLD_": str(1 << 40),
                                "MALLOC_TOP_PAD_": str(1 << 30)},
              "eigen_1thread": {"XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false"},
              "torch_eager": {"SV_TORCH": "1"}}


def child(width, reps):
    import jax
    import numpy as np
    from inbetween_jax.data import load_dataset
    from inbetween_jax.models.scvae import train as T
    from inbetween_jax.models.scvae.config import get_config
    from inbetween_jax.models.scvae.features import TrainData, compute_stats
    from inbetween_jax.train.loop import enable_compilation_cache, make_step_fn, strongly_typed
    enable_compilation_cache(os.environ["SV_CACHE"])
    win = load_dataset(None, "benchmark")
    data, stats = TrainData.from_windows(win), compute_stats(win)
    cfg = get_config(width)
    cfg = dataclasses.replace(cfg, data=dataclasses.replace(cfg.data, trans_max=50))
    rng = np.random.default_rng(0)
    np_batch = T.make_batch(data, rng.integers(0, len(data), 32), rng.integers(0, data.q.shape[1] - 51, 32), 51, 51)
    batch = jax.tree.map(jax.numpy.asarray, np_batch)
    step = make_step_fn(T.make_train_step(cfg, data.parents, 51), jax.random.key(1))
    holder = [jax.tree.map(strongly_typed, T.make_init_fn(cfg, stats, data.q.shape[2])(jax.random.key(0)))]

    def jax_call():
        holder[0], m = step(holder[0], batch, np.int32(0))
        jax.block_until_ready(m["loss"])
    call = jax_call                             # JAX's step, or (SV_TORCH=1) the PyTorch-eager reference's
    if os.environ.get("SV_TORCH"):
        from inbetween_jax.evaluation.torch_ref import scvae as torch_scvae
        call = torch_scvae.make_step(cfg, data.q.shape[2], data.parents, stats, np_batch, 51)
    rows = []
    for _ in range(reps + 1):
        r0, t0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
        call()
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        rows.append([round((time.perf_counter() - t0) * 1e3), r1.ru_minflt - r0.ru_minflt,     # ms, faults,
                     r1.ru_nvcsw - r0.ru_nvcsw, r1.ru_nivcsw - r0.ru_nivcsw,                    # switches,
                     round((r1.ru_utime - r0.ru_utime) * 1e3), round((r1.ru_stime - r0.ru_stime) * 1e3)])  # CPU ms
    print(json.dumps({"calls": rows[1:], "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024}))


def main(reps=6, rounds=2, width="paper", conds=None):
    have = {JE: ctypes.util.find_library("jemalloc"), TC: ctypes.util.find_library("tcmalloc_minimal")}
    names = [n for n in (conds or CONDITIONS) if have.get(CONDITIONS[n].get("LD_PRELOAD"), True)]
    env0 = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "LD_PRELOAD")}
    env0["SV_CACHE"] = tempfile.mkdtemp(prefix="sv-cache-")
    for r in range(rounds):
        for name in names[r % len(names):] + names[:r % len(names)]:
            out = subprocess.run([sys.executable, __file__, "--child", width, str(reps)], capture_output=True,
                                 text=True, env={**env0, **CONDITIONS[name]})
            res = json.loads(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 else {"err": out.stderr[-300:]}
            ms = sorted(c[0] for c in res.get("calls", [[0]]))
            print(json.dumps({"round": r, "cond": name, "median_ms": ms[len(ms) // 2], "min_ms": ms[0],
                              "max_ms": ms[-1], "load1": os.getloadavg()[0], **res}), flush=True)


if __name__ == "__main__":
    a = sys.argv[1:]
    if a[:1] == ["--child"]:
        child(a[1], int(a[2]))
    else:
        kw = dict(zip(a[0::2], a[1::2]))
        main(int(kw.get("--reps", 6)), int(kw.get("--rounds", 2)), kw.get("--width", "paper"),
             kw["--conds"].split(",") if "--conds" in kw else None)
