"""The S-CVAE transition bank on its own or blended with a run's network: Table-1 rows against Slerp.

    python experiments/scvae_bank_probe.py SOURCE [--bank fit] [--windows val] [--k 16,32,64] [--tau 0,0.5]
        [--weights 1,0.75] [--run RUN_DIR [--samples 2]] [--mirror]

Builds the transition bank of the ``--bank`` split of SOURCE (:func:`inbetween_jax.banks.scvae_bank`; ``fit``:
the training files without the validation ones; ``train``: all training files) and scores, on the ``--windows``
split (``val``: 65-frame validation windows at offset 20; ``benchmark``: the test windows), Slerp and the bank's
transitions mixed with Slerp's by each weight (1: the bank's alone), for every k and tau, in the S-CVAE paper's
Table-1 layout (one past keyframe; L2P, L2Q, NPSS at 10 / 30 / 50 frames).  Bank settings are chosen with
``--bank fit --windows val``, never on the test windows.  With ``--run`` the run's network samples (``--samples``
of them; on this bank's base if the run was trained with ``model.bank_base``) take Slerp's place in the blend, so
weight 0 is the network alone.  ``--mirror``: the bank holds each motion's mirror image as well.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("source")
    ap.add_argument("--bank", default="fit", choices=("fit", "train"))
    ap.add_argument("--windows", default="val", choices=("val", "benchmark"))
    ap.add_argument("--k", default="16,32,64")
    ap.add_argument("--tau", default="0,0.5")
    ap.add_argument("--weights", default="1,0.75")
    ap.add_argument("--run", default=None, help="an S-CVAE run folder: blend its samples instead of Slerp")
    ap.add_argument("--samples", type=int, default=2)
    ap.add_argument("--mirror", action="store_true", help="the bank holds each motion's mirror image too")
    a = ap.parse_args(argv)
    from inbetween_jax.banks import scvae_bank
    from inbetween_jax.baselines import interpolate_transition
    from inbetween_jax.data import l2p_stats, load_dataset, resolve_source
    from inbetween_jax.evaluation import transition_metrics
    from inbetween_jax.models.scvae.bank import blend, knn_transition
    t0 = time.time()
    source = resolve_source(a.source)
    bank = scvae_bank(None, source, a.bank, a.mirror)         # what inbetween build-bank writes
    windows = (load_dataset(source, "benchmark") if a.windows == "benchmark"
               else load_dataset(source, "val", window=65, offset=20))
    x_mean, x_std = l2p_stats(load_dataset(source, "train").global_pose()[1])
    print(f"bank: {a.bank} split, {len(bank.names)} clips, {bank.num_frames} frames; {len(windows)} {a.windows} "
          f"windows ({time.time() - t0:.0f} s)")
    n_past = 10
    trained = None
    if a.run:
        from inbetween_jax.models.scvae import infer
        from inbetween_jax.train.run import load_run
        trained = infer.load(load_run(a.run))
        print(f"network: {a.run} step {trained.step}")
    for length in (10, 30, 50):
        k0, k1 = n_past - 1, n_past + length
        q64, r64 = windows.local_quats.astype(np.float64), windows.root_pos.astype(np.float64)
        sq, sr = interpolate_transition(q64, r64, n_past, length)
        base = transition_metrics(windows, n_past, length, sq, sr, x_mean, x_std)
        print(f"{length} frames: Slerp L2P {base['L2P']:.4f} L2Q {base['L2Q']:.4f} NPSS {base['NPSS']:.4f}")
        mixed_q, mixed_r = sq[None], sr[None]          # (S, B, L, ...): what the bank is blended with
        if trained is not None:
            s = infer.sample_transitions(trained.cfg.model, trained.state, windows, n_past, length, a.samples,
                                         bank=bank, blend_bank=False)
            mixed_q, mixed_r = s["q"], s["r"]
        for k in map(int, a.k.split(",")):
            for tau in map(float, a.tau.split(",")):
                kq, kr, _ = knn_transition(bank, q64[:, k0], r64[:, k0], q64[:, k1], r64[:, k1], length, k, tau)
                for w in map(float, a.weights.split(",")):
                    bq, br = blend(mixed_q, mixed_r, kq, kr, w)
                    m = transition_metrics(windows, n_past, length, bq, br, x_mean, x_std)
                    print(f"  k {k:3d} tau {tau:g} weight {w:g}: L2P {m['L2P']:.4f} ({m['L2P'] / base['L2P']:.3f}x)  "
                          f"L2Q {m['L2Q'] / base['L2Q']:.3f}x  NPSS {m['NPSS'] / base['NPSS']:.3f}x", flush=True)
    print(f"wall {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
