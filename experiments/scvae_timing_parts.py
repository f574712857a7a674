"""Whole-body against part-wise timing variants (``model.timing_parts``) where the S-CVAE's gate falls back to
Slerp: there the sampled mode's samples are Slerp retimed (the bank's part is gated off), so any subject can score
them, the fit subjects included (no network is involved).  Windows every 40 frames of the validation and the fit
subjects' files; per activity group and length, the mean- and best-of-N joint position error over Slerp's.

    python experiments/scvae_timing_parts.py [--spreads 0.25,0.4] [--samples 10]     # about 3 min
"""
import argparse
import collections

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.data.windows import keyframe_pairs
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.models.scvae.gate import slerp_base
from inbetween_jax.models.scvae.timing import body_parts, retimed

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--spreads", default="0.25,0.4")
p.add_argument("--samples", type=int, default=10)
a = p.parse_args()
spreads = [float(s) for s in a.spreads.split(",")]
variants = [(f"{sp} {'parts' if parts else 'whole'}", sp, parts) for sp in spreads for parts in (False, True)]
res = collections.defaultdict(lambda: collections.defaultdict(list))
for split in ("val-subjects", "fit-subjects"):
    for m in load_motions("cmu", split):
        group, parts = activity_group(str(m.source)), body_parts(m.skeleton)
        for n, k0, k1, truth in keyframe_pairs(m):                                    # truth (B, n, J, 3)
            sq, sr = slerp_base(m.local_quats[k0], m.root_pos[k0], m.local_quats[k1], m.root_pos[k1], n)

            def errors(q, r):                                                            # (S, B) mean joint error
                lp = np.broadcast_to(m.local_pos[0], q.shape[:-1] + (3,)).copy()
                lp[..., 0, :] = r
                pos = forward_kinematics(q, lp, m.skeleton.parents)[1]
                return np.linalg.norm(pos - truth[None], axis=-1).mean((2, 3))
            e0 = errors(sq[None], sr[None])[0]
            row = []
            for _, spread, use_parts in variants:
                q, r = retimed(m.local_quats[k0], m.root_pos[k0], m.local_quats[k1], m.root_pos[k1],
                               np.repeat(sq[None], a.samples, 0), np.repeat(sr[None], a.samples, 0), spread,
                               parts if use_parts else None)
                e = errors(q, r) / e0[None]
                row.append(np.stack([e.mean(0), e.min(0)], 1))                            # (B, 2)
            res[split][(group, n)].append(np.stack(row, 1))                               # (B, V, 2)
print(f"mean-of-{a.samples} / best-of-{a.samples} joint error over Slerp's, Slerp retimed")
for split in res:
    print(f"\n| {split} | frames | windows | " + " | ".join(v[0] for v in variants) + " |")
    print("|---|---|---|" + "---|" * len(variants))
    pooled = collections.defaultdict(list)
    for (group, n), rows in sorted(res[split].items()):
        e = np.concatenate(rows)
        pooled[n].append(e)
        print(f"| {group} | {n} | {len(e)} | " + " | ".join(f"{x:.3f} / {y:.3f}" for x, y in e.mean(0)) + " |")
    for n, es in sorted(pooled.items()):
        e = np.concatenate(es)
        print(f"| all | {n} | {len(e)} | " + " | ".join(f"{x:.3f} / {y:.3f}" for x, y in e.mean(0)) + " |")
