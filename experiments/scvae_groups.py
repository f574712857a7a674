"""Where the S-CVAE's network helps: its fill alone (no gate, no sampled mode) against Slerp, per CMU activity
group and length, on any split of the ``cmu`` source -- its own training subjects (``fit-subjects``: what it
learned at all) or held-out ones -- with the share of windows its two-keyframe gate would send back to Slerp
(weight < 0.5), the network's ratio on those windows and the gated fill's ratio.

    python experiments/scvae_groups.py [RUN_DIR] [--split fit-subjects]

Default RUN_DIR: the shipped weights.  65-frame windows every 40 frames, one sample, 10 / 30 / 50 frames after 10
past frames; per-window joint error over Slerp's (mean, median).
"""
import argparse
import collections
import time

import numpy as np

from inbetween_jax.data import load_dataset
from inbetween_jax.data.activities import activity_group
from inbetween_jax.models.ood import load_gate
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.bench import per_frame_error
from inbetween_jax.models.scvae.gate import gate_windows, slerp_base
from inbetween_jax.shipped import shipped_run
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir", nargs="?", default=None)
p.add_argument("--split", default="fit-subjects")
a = p.parse_args()
t0 = time.time()
run = load_run(a.run_dir) if a.run_dir else shipped_run("scvae")
trained = infer.load(run)
fa = tuple(trained.extra.get("forward_axis") or trained.skeleton.forward_axis())
gate_pair = trained.gate or load_gate(run.run_dir)          # a run whose run.json leaves model.ood_gate off
w = load_dataset("cmu", a.split, window=65, offset=40)
rows = collections.defaultdict(list)
for n in (10, 30, 50):
    k0, k1 = 9, 10 + n
    keys = (w.local_quats[:, k0], w.root_pos[:, k0], w.local_quats[:, k1], w.root_pos[:, k1])
    s = infer.sample_transitions(trained.cfg.model, trained.state, w, 10, n, 1, bank=trained.bank, sampled=False)
    net = per_frame_error(w, 10, n, s["q"], s["r"])[0].mean(-1)
    bq, br = slerp_base(*keys, n)
    base = per_frame_error(w, 10, n, bq[None], br[None])[0].mean(-1)
    gq, gr, _, weight = gate_windows(gate_pair, w, k0, k1, s["q"], s["r"], fa)
    gated = per_frame_error(w, 10, n, gq, gr)[0].mean(-1)
    for i, name in enumerate(w.seq_names):
        b = max(base[i], 1e-6)
        rows[(activity_group(name.split("@")[0]), n)].append((net[i] / b, weight[i], gated[i] / b))
print(f"**{a.run_dir or 'shipped S-CVAE'}: {a.split}, {len(w)} windows, network alone over Slerp** "
      f"({time.time() - t0:.0f} s)\n")
print("| group | frames | windows | mean | median | gate weight (mean) | gate < 0.5 | network there (mean, median) "
      "| gated fill (mean) |")
print("|---|---|---|---|---|---|---|---|---|")
for (g, n), v in sorted(rows.items()):
    v = np.array(v)
    lo = v[:, 1] < 0.5
    there = f"{v[lo, 0].mean():.3f}, {np.median(v[lo, 0]):.3f}" if lo.any() else "-"
    print(f"| {g} | {n} | {len(v)} | {v[:, 0].mean():.3f} | {np.median(v[:, 0]):.3f} | {v[:, 1].mean():.2f} | "
          f"{lo.mean():.0%} | {there} | {v[:, 2].mean():.3f} |")
