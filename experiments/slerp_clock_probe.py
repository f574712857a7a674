"""Is there a better non-learned fill between two keyframes than Slerp on a linear clock?  Where the S-CVAE's gate
falls back (two keyframes alone, motion the network never saw), its fill is Slerp; a better base there would lower
the two-keyframe ratio that stays at 0.99-1.00x Slerp on the test subjects (docs/results/gate.md).

Slerp / lerp replayed on a symmetric eased clock ``w(t) = t - e sin(2 pi t) / (2 pi)`` (``e`` > 0: slow at both
keyframes, ease-in / ease-out; ``e`` < 0: fast at both), on every window (every 40 frames) of the validation and
the fit subjects' files; no network, so any subject can score it.  Two variants: the whole body on the eased clock,
and the joints alone (the root kept on the linear clock).  Rows: activity group and length, then the windows where the
shipped S-CVAE gate falls fully back to Slerp (its travel score at or above its ``hi``: keyframes in place), then
all windows.  Joint position error over Slerp's.

    python experiments/slerp_clock_probe.py                # about 1 min
"""
import collections

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.data.windows import keyframe_pairs
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.geometry.quaternion import quat_align, quat_slerp

EASES = (-0.25, 0.0, 0.25, 0.5, 0.75)
with np.load("inbetween_jax/assets/weights/scvae/ood.npz") as z:       # the shipped gate: TravelScore, lo / hi
    TRAVEL_C, GATE_HI = float(z["travel_c"]), float(z["gate_hi"])
res = collections.defaultdict(list)
for split in ("val-subjects", "fit-subjects"):
    for m in load_motions("cmu", split):
        group = activity_group(str(m.source))
        for n, k0, k1, truth in keyframe_pairs(m):                                # truth (B, n, J, 3)
            q0 = m.local_quats[k0].astype(np.float64)
            q1 = quat_align(m.local_quats[k1].astype(np.float64), q0)
            r0, r1 = m.root_pos[k0].astype(np.float64), m.root_pos[k1].astype(np.float64)
            t = np.arange(1, n + 1) / (n + 1)
            errors = []
            for joints_only in (False, True):
                for e in EASES:
                    w = t - e * np.sin(2 * np.pi * t) / (2 * np.pi)
                    q = quat_slerp(q0[:, None], q1[:, None], w[None, :, None])
                    wr = t if joints_only else w
                    lp = np.broadcast_to(m.local_pos[0], q.shape[:-1] + (3,)).copy()
                    lp[..., 0, :] = r0[:, None] + wr[None, :, None] * (r1 - r0)[:, None]
                    pos = forward_kinematics(q, lp, m.skeleton.parents)[1]
                    errors.append(np.linalg.norm(pos - truth, axis=-1).mean((1, 2)))
            errors = np.stack(errors, 1)                                              # (B, 2 x len(EASES))
            ratio = errors / errors[:, [EASES.index(0.0)]]
            speed = np.linalg.norm((r1 - r0)[:, [0, 2]], axis=1) / (n + 1)          # TravelScore's, per frame
            fallback = 1.0 / (1.0 + speed / TRAVEL_C) >= GATE_HI
            res[(split, group, n)].append(ratio)
            res[(split, "gate falls back", n)].append(ratio[fallback])

head = " | ".join(f"e {e:+g}" for e in EASES)
print(f"| split | group | frames | windows | whole body: {head} | joints only: {head} |")
print("|---|---|---|---|" + "---|" * (2 * len(EASES)))
pooled = collections.defaultdict(list)
for (split, group, n), rows in sorted(res.items(), key=lambda kv: (kv[0][0], kv[0][1] == "gate falls back", kv[0][1:])):
    e = np.concatenate(rows)
    if group != "gate falls back":
        pooled[(split, n)].append(e)
    if len(e):
        print(f"| {split} | {group} | {n} | {len(e)} | " + " | ".join(f"{x:.3f}" for x in e.mean(0)) + " |")
for (split, n), es in sorted(pooled.items()):
    e = np.concatenate(es)
    print(f"| {split} | all | {n} | {len(e)} | " + " | ".join(f"{x:.3f}" for x in e.mean(0)) + " |")
