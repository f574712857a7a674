"""Eased clocks for the S-CVAE's samples between two keyframes (docs/results/scvae.md, "Eased clocks"); not shipped.

    python experiments/scvae_timing_ease.py [--run RUN_DIR] [--split val-subjects] [--set KEY=VALUE ...]
                                            [--try 0:all-] [--try 0.3:all-] ...

The shipped sampled mode replays samples s >= 1 earlier or later (``u = t + a sin(pi t) / pi``,
:func:`inbetween_jax.models.scvae.timing.retimed`).  A clock of that family moves the whole in-between; it never
makes it slow near both keyframes and fast between (or the reverse), which is how much captured motion between two
poses goes.  Each ``--try E:PATTERN`` adds the second harmonic ``e_s sin(2 pi t) / (2 pi)`` to sample s's clock
(``retimed(..., ease=)``), ``e_s = E * sign_s * (1 - w)``: only where the out-of-distribution gate (weight w) falls
back to Slerp, the windows whose samples differ by their timing alone.  PATTERN gives sign_s for samples 1..9:
``all-`` (all slow at the keyframes), ``all+``, ``alt`` (- + - + ...), ``half-`` (- 0 - 0 ...).  ``0:all-`` is the
shipped sampled mode.

Printed per length: the mean of ten against the fill (L2P, the sampled mode's 3 % rule) and the best of ten over
Slerp's joint error, on all windows and on those where the gate falls back (weight < 0.5).  ``--run`` takes a run
folder (default: the shipped weights); ``--set`` its inference switches (a run trained without some subjects gets
the shipped ones this way).
"""
import argparse
import dataclasses
import time

import numpy as np

from inbetween_jax import shipped
from inbetween_jax.baselines import interpolate_transition
from inbetween_jax.data import l2p_stats, load_dataset
from inbetween_jax.evaluation.samples import per_window_l2p, window_positions
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.bank import bank_sample_blend, sample_timing_spread, sample_weight
from inbetween_jax.models.scvae.timing import body_parts, retimed
from inbetween_jax.train.run import load_run

N_PAST, S = 10, 10
PATTERNS = {"all-": lambda s: -np.ones(len(s)), "all+": lambda s: np.ones(len(s)),
            "alt": lambda s: np.where(s % 2 == 1, -1.0, 1.0), "half-": lambda s: np.where(s % 2 == 1, -1.0, 0.0)}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", default=None, help="run folder (default: the shipped weights)")
    p.add_argument("--split", default="val-subjects")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--try", dest="tries", action="append", default=None, metavar="E:PATTERN")
    a = p.parse_args()
    tries = a.tries or ["0:all-", "0.3:all-", "0.3:alt", "0.3:half-"]
    t0 = time.time()
    run = shipped.shipped_run("scvae") if a.run is None else load_run(a.run)
    run = dataclasses.replace(run, config=shipped.config_with_overrides(run.model, run.config, a.set))
    tr = infer.load(run)
    cfg = tr.cfg.model
    if not (cfg.ood_gate and tr.gate is not None):
        p.error("the run needs its out-of-distribution gate: a calibrated folder and --set model.ood_gate=true")
    fa = np.asarray(tr.extra.get("forward_axis") or tr.skeleton.forward_axis(), np.float64)
    val = load_dataset("cmu", a.split, window=65, offset=20)
    x_mean, x_std = l2p_stats(val.global_pose()[1])
    parts = body_parts(val.skeleton) if cfg.timing_parts else None
    s_idx = np.arange(S)
    print(f"{a.run or 'shipped weights'}, {a.split}: {len(val.local_quats)} windows\n")
    print("| frames | ease E : pattern | mean of 10 vs the fill | best of 10 / Slerp | where the gate falls back: "
          "mean vs fill | best / Slerp | windows falling back |\n|---|---|---|---|---|---|---|")
    for n in (10, 30, 50):
        k = (val.local_quats[:, N_PAST - 1], val.root_pos[:, N_PAST - 1], val.local_quats[:, N_PAST + n],
             val.root_pos[:, N_PAST + n])
        gated = infer.sample_transitions(cfg, tr.state, val, N_PAST, n, S, bank=tr.bank, gate=tr.gate,
                                         forward_axis=fa, sampled=False)                 # the fill, gated
        w = np.clip(gated["gate_weight"], 0.0, 1.0)
        q, r = bank_sample_blend(tr.bank, *k, gated["q"], gated["r"], sample_weight(cfg, w), 0.0)   # not retimed
        sq, sr = interpolate_transition(val.local_quats.astype(np.float64), val.root_pos.astype(np.float64),
                                        N_PAST, n)
        truth = window_positions(val, val.local_quats[:, N_PAST:N_PAST + n], val.root_pos[:, N_PAST:N_PAST + n])

        def errors(qs, rs):
            pos = np.stack([window_positions(val, qi, ri) for qi, ri in zip(qs, rs)])
            return np.linalg.norm(pos - truth, axis=-1).mean((-1, -2)), per_window_l2p(pos, truth, x_mean, x_std)
        slerp_cm = errors(sq[None], sr[None])[0][0]
        fb = w < 0.5
        fill = None
        for spec in tries:
            e, pattern = spec.split(":")
            sign = PATTERNS[pattern](s_idx)
            sign[0] = 0.0
            ease = float(e) * sign[:, None] * (1.0 - w)[None]                                 # (S, B)
            qq, rr = retimed(*k, q, r, sample_timing_spread(cfg, w), parts, ease=ease)
            cm, l2p = errors(qq, rr)
            fill = l2p[0] if fill is None else fill
            best, best_fb = cm.min(0).mean() / slerp_cm.mean(), cm[:, fb].min(0).mean() / slerp_cm[fb].mean()
            print(f"| {n} | {spec} | {l2p.mean() / fill.mean() - 1:+.1%} | {best:.3f} "
                  f"| {l2p[:, fb].mean() / fill[fb].mean() - 1:+.1%} | {best_fb:.3f} | {int(fb.sum())} |", flush=True)
    print(f"\n({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
