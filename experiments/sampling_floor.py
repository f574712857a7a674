"""S-CVAE sampling (10 samples x 1 keyframe pair x a 50-frame transition, as ``inbetween speed`` times it) against
two floors: the FLOP floor (its matmul FLOPs at the machine's measured square-GEMM peak) and the weight-traffic
floor (every rollout step multiplies 10 rows by every generator weight, so each step streams the generators'
weights from memory once: rollout steps x weight bytes, at the machine's read bandwidth and at the rate XLA's own
10-row GEMM reaches on one large matrix).  One process, medians of 15 calls.

    python experiments/sampling_floor.py [--preset paper]
"""
import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax import xla_cpu
from inbetween_jax.data import load_dataset
from inbetween_jax.models.scvae import model as scvae
from inbetween_jax.models.scvae import train as scvae_train
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.models.scvae.features import compute_stats
from inbetween_jax.profiling import matmul_flops, median_ms, time_calls

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--preset", default="paper")
a = p.parse_args()
xla_cpu.configure("scvae")
win = load_dataset("embedded", "benchmark")
cfg = get_config(a.preset)
state = scvae_train.make_init_fn(cfg, compute_stats(win), int(win.local_quats.shape[2]))(jax.random.key(0))
params, stats = state["params"], state["stats"]
length = 51
sample = jax.jit(lambda p_, s, t, k: scvae.sample(p_, cfg.model, stats, s, t, length, k, length)["out"])
pick = lambda x, f: jnp.asarray(x[:1, f])  # noqa: E731
start = {"q": pick(win.local_quats, 0), "r": pick(win.root_pos, 0), "c": pick(win.contacts, 0)}
target = {"q": pick(win.local_quats, length), "r": pick(win.root_pos, length), "c": pick(win.contacts, length)}
keys = jax.random.split(jax.random.key(2), 10)
jax.block_until_ready(sample(params, start, target, keys))
ms = median_ms(time_calls(lambda: sample(params, start, target, keys), reps=15, warmup=2))
flops = matmul_flops(lambda q: sample(q, start, target, keys), params)
weight_bytes = sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(params))
steps = scvae.num_scan_steps(cfg.model, length)                             # one scan step runs both generators


def rate(fn, nbytes, reps=15):
    fn()
    return nbytes / np.median([(lambda t0: (fn(), time.perf_counter() - t0)[1])(time.perf_counter())
                               for _ in range(reps)])


def read_rate():
    big = np.ones(256 * 1024 * 1024, np.float32)                            # 1 GiB
    return rate(lambda: big.sum(), big.nbytes)


read_bw = read_rate()
w = jnp.ones((4096, 6144), jnp.float32)
x = jnp.ones((10, 4096), jnp.float32)
mm = jax.jit(lambda x_, w_: x_ @ w_)
gemm_bw = rate(lambda: mm(x, w).block_until_ready(), w.size * 4)
sq = jnp.ones((2048, 2048), jnp.float32)
peak = rate(lambda: mm(sq, sq).block_until_ready(), 2 * 2048 ** 3)          # FLOP/s
traffic = steps * weight_bytes
print(f"S-CVAE {a.preset}: 10 samples x 1 pair x {length - 1} frames: {ms:.1f} ms")
print(f"  matmul FLOPs {flops / 1e9:.2f} G; square-GEMM peak {peak / 1e9:.1f} GFLOP/s -> FLOP floor "
      f"{1e3 * flops / peak:.1f} ms ({ms / (1e3 * flops / peak):.2f}x)")
print(f"  generator weights {weight_bytes / 1e6:.1f} MB x {steps} rollout steps = {traffic / 1e9:.2f} GB streamed")
print(f"  read bandwidth {read_bw / 1e9:.1f} GB/s -> traffic floor {1e3 * traffic / read_bw:.1f} ms "
      f"({ms / (1e3 * traffic / read_bw):.2f}x)")
print(f"  XLA 10-row GEMM on a 4096 x 6144 matrix streams {gemm_bw / 1e9:.1f} GB/s -> {1e3 * traffic / gemm_bw:.1f} ms "
      f"({ms / (1e3 * traffic / gemm_bw):.2f}x)")
