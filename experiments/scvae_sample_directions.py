"""Two more directions for the S-CVAE's samples between two keyframes, tried on the validation subjects with the
shipped weights (docs/results/scvae.md, "Two more sample directions"); neither is in the package.

    python experiments/scvae_sample_directions.py [--split val-subjects]

1. **Gate-weight spread.** Samples s >= 1 take the gate's weight moved toward the other end by ``a_s``
   (``w_s = (1 - a_s) w + a_s (1 - w)``; ``a_s`` = 1/3, 2/3 or 1 of ``amp``): where the gate falls back to Slerp
   some samples keep part of the network's fill, where it keeps the network some lean toward Slerp.
2. **Principal directions of Slerp's residual.** The truth minus Slerp on the fit subjects' windows where the
   gate falls back (local joint rotations as rotation vectors, weighted by the joint's lever over its
   descendants, plus the root's offset in the start keyframe's facing space), its principal components;
   sample pairs s >= 1 move by +- ``c`` standard deviations along the first ``K`` components, scaled by
   ``1 - w``.

Both are applied before the shipped sampled mode (bank blend, retiming), as the gate's blend is.  Printed per
length: the mean of ten against the fill (L2P, the sampled mode's 3 % rule) and the best of ten over Slerp's joint
error, on all windows and on those where the gate falls back (weight < 0.5).
"""
import argparse
import time

import numpy as np

from inbetween_jax.baselines import interpolate_transition
from inbetween_jax.data import l2p_stats, load_dataset
from inbetween_jax.evaluation.samples import per_window_l2p, window_positions
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.geometry.quaternion import (quat_from_axis_angle, quat_inv, quat_mul, quat_rotate,
                                               quat_to_axis_angle)
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.bank import bank_sample_blend, keyframe_space, sample_timing_spread, sample_weight
from inbetween_jax.models.scvae.gate import gate_blend, keyframe_context, slerp_base
from inbetween_jax.models.scvae.timing import body_parts
from inbetween_jax.shipped import shipped_run

N_PAST, S = 10, 10


def rotvec(q):
    axis, angle = quat_to_axis_angle(q)
    return axis * np.where(angle > np.pi, angle - 2 * np.pi, angle)[..., None]


def from_rotvec(v):
    angle = np.linalg.norm(v, axis=-1)
    return quat_from_axis_angle(v / np.maximum(angle, 1e-12)[..., None], angle)


def yaw_quat(yaw):
    """Turns about +Y by ``yaw`` (N,) radians: (N, 4)."""
    return quat_from_axis_angle(np.broadcast_to([0.0, 1.0, 0.0], np.shape(yaw) + (3,)), np.asarray(yaw, np.float64))


TABLE_HEAD = ("| frames | samples | mean of 10 vs the fill | best of 10 / Slerp | where the gate falls back: mean vs "
              "fill | best / Slerp |\n|---|---|---|---|---|---|")


def sample_errors(ds, q, r, n, x_mean, x_std):
    """Samples q (S, B, n, J, 4), r (S, B, n, 3) of the n-frame transitions after frame N_PAST - 1 of ``ds``:
    mean joint error (cm) and L2P per sample and window, each (S, B)."""
    truth = window_positions(ds, ds.local_quats[:, N_PAST:N_PAST + n], ds.root_pos[:, N_PAST:N_PAST + n])
    pos = np.stack([window_positions(ds, qs, rs) for qs, rs in zip(q, r)])
    return np.linalg.norm(pos - truth, axis=-1).mean((-1, -2)), per_window_l2p(pos, truth, x_mean, x_std)


def slerp_residual(ds, n, lever, yaw):
    """(B, n, D): truth minus Slerp over the n-frame transitions after frame N_PAST - 1: each joint's rotation
    vector times its ``lever`` (J, 1), then the root's offset in the facing space of ``yaw`` (B,)."""
    q, r = ds.local_quats.astype(np.float64), ds.root_pos.astype(np.float64)
    sq, sr = interpolate_transition(q, r, N_PAST, n)
    d = rotvec(quat_mul(quat_inv(sq), q[:, N_PAST:N_PAST + n])) * lever                      # (B, n, J, 3)
    dr = quat_rotate(np.broadcast_to(yaw_quat(-yaw)[:, None], sr.shape[:-1] + (4,)), r[:, N_PAST:N_PAST + n] - sr)
    return np.concatenate([d.reshape(len(q), n, -1), dr], -1)


def moved_by(q, r, res, yaw, lever):
    """q (B, n, J, 4), r (B, n, 3) moved by a residual (B, n, D) in :func:`slerp_residual`'s form (joints with no
    lever, the leaves, are not turned)."""
    nj = q.shape[-2]
    d = res[..., :nj * 3].reshape(res.shape[:-1] + (nj, 3)) / np.maximum(lever, 1e-6)
    dr = quat_rotate(np.broadcast_to(yaw_quat(yaw)[:, None], r.shape[:-1] + (4,)), res[..., nj * 3:])
    return quat_mul(q, from_rotvec(d)), r + dr


def levers(skel) -> np.ndarray:
    """(J,) per joint: the RMS distance of its descendants to it in the rest pose (cm per radian of turn)."""
    j = len(skel.parents)
    _, rest = forward_kinematics(np.tile([1.0, 0, 0, 0], (1, j, 1)), np.asarray(skel.offsets, np.float64)[None],
                                 skel.parents)
    desc = [[i] for i in range(j)]
    for i in range(j - 1, 0, -1):
        desc[skel.parents[i]] += desc[i]
    return np.array([np.sqrt(np.sum((rest[0, d] - rest[0, i]) ** 2) / j) for i, d in enumerate(desc)])


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--split", default="val-subjects")
    a = p.parse_args()
    t0 = time.time()
    tr = infer.load(shipped_run("scvae"))
    cfg = tr.cfg.model
    fa = np.asarray(tr.extra.get("forward_axis") or tr.skeleton.forward_axis(), np.float64)
    val = load_dataset("cmu", a.split, window=65, offset=20)
    fit = load_dataset("cmu", "fit-subjects", window=65, offset=20)
    x_mean, x_std = l2p_stats(val.global_pose()[1])
    lever = levers(val.skeleton)[:, None]
    parts = body_parts(val.skeleton) if cfg.timing_parts else None

    def keys(ds, n):
        return (ds.local_quats[:, N_PAST - 1], ds.root_pos[:, N_PAST - 1], ds.local_quats[:, N_PAST + n],
                ds.root_pos[:, N_PAST + n])

    def gate_weight(ds, n):
        return tr.gate[1].weight(tr.gate[0].score(keyframe_context(*keys(ds, n), n, ds.skeleton, fa)))

    def residual(ds, n):
        yaw, _ = keyframe_space(ds.local_quats[:, N_PAST - 1, 0].astype(np.float64),
                                ds.root_pos[:, N_PAST - 1].astype(np.float64), fa)
        return slerp_residual(ds, n, lever, yaw).reshape(len(yaw), -1), yaw

    def moved(q, r, vec, yaw, n):
        return moved_by(q, r, vec.reshape(len(q), n, -1), yaw, lever)

    def errors(q, r, n):
        return sample_errors(val, q, r, n, x_mean, x_std)

    print(TABLE_HEAD)
    for n in (10, 30, 50):
        net = infer.sample_transitions(cfg, tr.state, val, N_PAST, n, S, bank=tr.bank, sampled=False)
        k = keys(val, n)
        w = gate_weight(val, n)
        base_q, base_r = slerp_base(*k, n)
        sq, sr = interpolate_transition(val.local_quats.astype(np.float64), val.root_pos.astype(np.float64),
                                        N_PAST, n)
        slerp_cm = errors(sq[None], sr[None], n)[0][0]
        fb = w < 0.5
        fill_l2p = None

        def report(name, per_sample_weight, vec=None):
            nonlocal fill_l2p
            q, r = np.empty(net["q"].shape), np.empty(net["r"].shape)
            for i in range(S):
                qi, ri = gate_blend(net["q"][i:i + 1], net["r"][i:i + 1], base_q, base_r, per_sample_weight[i])
                q[i], r[i] = qi[0], ri[0]
                if vec is not None:
                    q[i], r[i] = moved(q[i], r[i], vec[i], yaw, n)
            q, r = bank_sample_blend(tr.bank, *k, q, r, sample_weight(cfg, w), sample_timing_spread(cfg, w), parts)
            cm, l2p = errors(q, r, n)
            fill_l2p = l2p[0] if fill_l2p is None else fill_l2p
            print(f"| {n} | {name} | {l2p.mean() / fill_l2p.mean() - 1:+.1%} "
                  f"| {cm.min(0).mean() / slerp_cm.mean():.3f} | {l2p[:, fb].mean() / fill_l2p[fb].mean() - 1:+.1%} | "
                  f"{cm[:, fb].min(0).mean() / slerp_cm[fb].mean():.3f} |", flush=True)

        report("shipped", np.broadcast_to(w, (S, len(w))))
        for amp in (0.2, 0.5):
            a_s = np.array([0.0] + [amp * (i % 3 + 1) / 3 for i in range(S - 1)])
            report(f"gate-weight spread {amp}", (1 - a_s[:, None]) * w[None] + a_s[:, None] * (1 - w[None]))
        res, _ = residual(fit, n)
        res = res[gate_weight(fit, n) < 0.5]
        _, sv, vt = np.linalg.svd(res - res.mean(0), full_matrices=False)
        sd = sv / np.sqrt(len(res))
        _, yaw = residual(val, n)
        for K in (1, 3):
            for c in (0.1, 0.5):
                vec = np.zeros((S, len(w), vt.shape[1]))
                for i in range(1, S):
                    j = (i - 1) // 2 % K
                    vec[i] = (1 if i % 2 else -1) * c * sd[j] * vt[j] * (1 - w)[:, None]
                report(f"residual PCs K={K}, c={c}", np.broadcast_to(w, (S, len(w))), vec)
    print(f"({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
