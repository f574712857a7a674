"""What the frames before the start keyframe are worth: the paper's Table-1 protocol gives the S-CVAE two keyframes,
while the benchmark windows (and the official LaFAN1 protocol) also hold the 10 frames before the start.

    python experiments/scvae_past_frames.py [RUN_DIR] [--split val-subjects] [--samples 10]

Per length (10 / 30 / 50 frames after 10 past frames; 65-frame windows at offset 20, as
``experiments/scvae_samples.py``), L2P over Slerp's of: the Hermite path through the two frames before the start
(``context.in_clip`` with ``use_after=False``, the run's ``model.context_*`` switches), the same through the frames on
both sides, the S-CVAE's gated two-keyframe fill (the Table-1 row), and that fill moved onto each path with the
in-clip gate (as ``inbetween infill`` fills a gap with the frames beside it known).  Default RUN_DIR: the shipped
weights.  No test split is read unless named.
"""
import argparse
import dataclasses
import time

import numpy as np

from inbetween_jax.baselines import interpolate_transition
from inbetween_jax.data import l2p_stats, load_dataset
from inbetween_jax.evaluation import markdown_table, transition_metrics
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.context import in_clip
from inbetween_jax.models.scvae.gate import gate_windows
from inbetween_jax.shipped import config_with_overrides, shipped_run
from inbetween_jax.train.run import load_run

N_PAST = 10
p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir", nargs="?", default=None)
p.add_argument("--split", default="val-subjects")
p.add_argument("--samples", type=int, default=10)
p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="inference switches of the run")
a = p.parse_args()
t0 = time.time()
run = load_run(a.run_dir) if a.run_dir else shipped_run("scvae")
run = dataclasses.replace(run, config=config_with_overrides(run.model, run.config, a.set))
trained = infer.load(run)
if trained.gate is None:
    raise SystemExit(f"{a.run_dir or 'the shipped S-CVAE'}: no out-of-distribution gate (ood.npz); calibrate one first")
mc = trained.cfg.model
val = load_dataset("cmu", a.split, window=65, offset=20)
x_mean, x_std = l2p_stats(val.global_pose()[1])
fa = tuple(trained.extra.get("forward_axis") or val.skeleton.forward_axis())
clip_gate = (trained.gate[0], trained.context_gate) if trained.context_gate is not None else trained.gate
rows = []
for n in (10, 30, 50):
    s = infer.sample_transitions(mc, trained.state, val, N_PAST, n, a.samples, sampled=False)      # no gate yet
    k0, k1 = N_PAST - 1, N_PAST + n
    fill_q, fill_r = gate_windows(trained.gate, val, k0, k1, s["q"], s["r"], fa)[:2]
    clip_q, clip_r = gate_windows(clip_gate, val, k0, k1, s["q"], s["r"], fa)[:2]
    variants = [("S-CVAE, two keyframes (Table 1)", fill_q, fill_r)]
    for after, side in ((False, "the frames before the start"), (True, "the frames on both sides")):
        cq, cr, hq, hr = in_clip(val, N_PAST, n, clip_q, clip_r, mc, use_after=after)
        gq, gr = in_clip(val, N_PAST, n, fill_q, fill_r, mc, use_after=after)[:2]
        variants += [(f"Hermite through {side}", hq, hr), (f"S-CVAE onto the Hermite path through {side}", cq, cr),
                     ("... with the two-keyframe gate", gq, gr)]
    sq, sr = interpolate_transition(val.local_quats.astype(np.float64), val.root_pos.astype(np.float64), N_PAST, n)
    slerp = transition_metrics(val, N_PAST, n, sq, sr, x_mean, x_std)["L2P"]
    for name, q, r in variants:
        l2p = transition_metrics(val, N_PAST, n, q, r, x_mean, x_std)["L2P"]
        rows.append({"frames": n, "method": name, "L2P": l2p, "x Slerp": l2p / slerp})
print(markdown_table(rows, ("L2P", "x Slerp"), f"{a.run_dir or 'shipped S-CVAE'} {' '.join(a.set)}: {a.split}, "
                     f"{len(val)} windows, {a.samples} samples ({time.time() - t0:.0f} s)"))
