"""Several hypotheses of the in-between from two keyframes, trained with a best-of-K (winner-takes-all) loss, as the
S-CVAE's samples where its gate falls back to Slerp (issue 38's "best-of-N reconstruction term"; not kept,
docs/results/scvae.md "Samples from a best-of-K head").

    python experiments/scvae_hypotheses.py [--fit fit-subjects] [--val val-subjects] [--run DIR [--set K=V ...]]
        [--hidden 64] [--modes 3] [--eps 0.2,0.5] [--lams 0.25,0.5] [--steps 3000] [--fallback-spread 0.6]   # 45-120 s

A small MLP maps the two keyframes (in the start's facing space) and the gap length to K residual paths over Slerp
(joint rotations weighted by their lever, the root's offset in facing space; the first M sine modes of the gap, so
every hypothesis meets both keyframes). Trained on the fit split with the relaxed winner-takes-all loss
``(1 - eps) min_k e_k + eps mean_k e_k`` (targets over ``n / 50``, so short gaps count); the step (every 250)
is chosen on the validation split's best-of-K loss. Then
samples s >= 1 of the shipped sampled mode are moved by ``lam (1 - w)`` times hypothesis s (w the gate's weight),
with the retiming spread where the gate falls back set to ``--fallback-spread``. Printed as
scvae_sample_directions.py prints its rows.
"""
import argparse
import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from inbetween_jax import shipped
from inbetween_jax.baselines import interpolate_transition
from inbetween_jax.data import l2p_stats, load_dataset
from inbetween_jax.geometry.quaternion import quat_mul, quat_rotate
from inbetween_jax.models.scvae import infer
from inbetween_jax.models.scvae.bank import bank_sample_blend, keyframe_space, sample_weight
from inbetween_jax.models.scvae.gate import gate_blend, keyframe_context, slerp_base
from inbetween_jax.models.scvae.timing import body_parts
from inbetween_jax.shipped import shipped_run
from inbetween_jax.train.run import load_run
from scvae_sample_directions import (TABLE_HEAD, levers, moved_by, rotvec, sample_errors, slerp_residual,
                                     yaw_quat)

N_PAST, S = 10, 10


def sine_basis(n, m):
    """(n, m): sin(pi k i / (n + 1)) for gap frames i = 1..n, modes k = 1..m (zero at both keyframes)."""
    i = np.arange(1, n + 1)[:, None]
    return np.sin(np.pi * np.arange(1, m + 1)[None] * i / (n + 1))


def features(ds, n, fa):
    """(B, F): both keyframes in the start's facing space, the root's travel, heights and the gap length."""
    q0, r0 = ds.local_quats[:, N_PAST - 1].astype(np.float64), ds.root_pos[:, N_PAST - 1].astype(np.float64)
    q1, r1 = ds.local_quats[:, N_PAST + n].astype(np.float64), ds.root_pos[:, N_PAST + n].astype(np.float64)
    yaw, _ = keyframe_space(q0[:, 0], r0, fa)
    yq = yaw_quat(-yaw)
    b = len(q0)
    parts = [rotvec(quat_mul(yq, q0[:, 0])), rotvec(quat_mul(yq, q1[:, 0])), rotvec(q0[:, 1:]).reshape(b, -1),
             rotvec(q1[:, 1:]).reshape(b, -1), quat_rotate(yq, r1 - r0) / 100, r0[:, 1:2] / 100, r1[:, 1:2] / 100,
             np.full((b, 1), n / 50)]
    return np.concatenate(parts, -1), yaw


def gap_scale(n):
    """Coefficients are learnt over this scale, so short gaps weigh as much as long ones in the loss (Slerp's
    residual grows about linearly with the gap on the fit windows)."""
    return n / 50.0


def dataset(ds, lengths, fa, lever, m):
    xs, cs = [], []
    for n in lengths:
        x, yaw = features(ds, n, fa)
        res = slerp_residual(ds, n, lever, yaw)
        xs.append(x)
        cs.append(np.einsum("nm,bnd->bmd", sine_basis(n, m), res) * 2 / (n + 1) / gap_scale(n))
    return np.concatenate(xs).astype(np.float32), np.concatenate(cs).astype(np.float32)


def init_mlp(key, sizes):
    params = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        key, k = jax.random.split(key)
        params.append((jax.random.normal(k, (a, b)) * np.sqrt(1.0 / a), jnp.zeros(b)))
    return params


def mlp(params, x):
    for w, b in params[:-1]:
        x = jax.nn.gelu(x @ w + b)
    w, b = params[-1]
    return x @ w + b


def train(x, c, xv, cv, k, hidden, eps, steps, seed, lr=1e-3, batch=256):
    """Relaxed winner-takes-all over K hypotheses; returns (params, mean, std, step chosen on validation)."""
    mu, sd = x.mean(0), x.std(0) + 1e-3
    m, d = c.shape[1:]
    params = init_mlp(jax.random.PRNGKey(seed), [x.shape[1], hidden, hidden, k * m * d])
    opt = optax.adamw(optax.cosine_decay_schedule(lr, steps), weight_decay=1e-4)
    state = opt.init(params)

    def errors(p, xb, cb):
        out = mlp(p, (xb - mu) / sd).reshape(len(xb), k, m, d)
        return jnp.sum((out - cb[:, None]) ** 2, (-1, -2))                  # (B, K)

    def loss(p, xb, cb):
        e = errors(p, xb, cb)
        return jnp.mean((1 - eps) * e.min(1) + eps * e.mean(1))

    @jax.jit
    def step(p, s, xb, cb):
        l, g = jax.value_and_grad(loss)(p, xb, cb)
        u, s = opt.update(g, s, p)
        return optax.apply_updates(p, u), s, l

    val_best = jax.jit(lambda p: errors(p, xv, cv).min(1).mean())
    rng = np.random.default_rng(seed)
    best = (np.inf, None, 0)
    for i in range(1, steps + 1):
        idx = rng.integers(0, len(x), batch)
        params, state, _ = step(params, state, x[idx], c[idx])
        if i % 250 == 0:
            v = float(val_best(params))
            if v < best[0]:
                best = (v, params, i)
    return best[1], mu, sd, best[2], best[0]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fit", default="fit-subjects")
    p.add_argument("--val", default="val-subjects")
    p.add_argument("--run", default=None, help="run folder (default: the shipped weights)")
    p.add_argument("--modes", type=int, default=3)
    p.add_argument("--hidden", type=int, default=64)
    p.add_argument("--eps", default="0.2,0.5")
    p.add_argument("--lams", default="0.25,0.5")
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--fallback-spread", default="0.6")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="inference switches of --run")
    a = p.parse_args()
    t0 = time.time()
    run = load_run(a.run) if a.run else shipped_run("scvae")
    tr = infer.load(dataclasses.replace(run, config=shipped.config_with_overrides(run.model, run.config, a.set)))
    cfg = tr.cfg.model
    fa = np.asarray(tr.extra.get("forward_axis") or tr.skeleton.forward_axis(), np.float64)
    val = load_dataset("cmu", a.val, window=65, offset=20)
    fit = load_dataset("cmu", a.fit, window=65, offset=10)
    x_mean, x_std = l2p_stats(val.global_pose()[1])
    lever = levers(val.skeleton)[:, None]
    parts = body_parts(val.skeleton) if cfg.timing_parts else None
    lengths = (10, 15, 20, 25, 30, 35, 40, 45, 50)
    x, c = dataset(fit, lengths, fa, lever, a.modes)
    xv, cv = dataset(val, (10, 30, 50), fa, lever, a.modes)
    print(f"fit {fit.local_quats.shape[0]} windows -> {len(x)} examples; ({time.time() - t0:.0f} s)", flush=True)
    nets = {}
    for eps in map(float, a.eps.split(",")):
        params, mu, sd, at, v = train(x, c, xv, cv, S - 1, a.hidden, eps, a.steps, 0)
        one = float(np.mean(np.sum(cv ** 2, (-1, -2))))
        print(f"eps {eps}: step {at}, validation best-of-{S - 1} coefficient error {v:.1f} (Slerp's {one:.1f}) "
              f"({time.time() - t0:.0f} s)", flush=True)
        nets[eps] = (params, mu, sd)

    def errors(q, r, n):
        return sample_errors(val, q, r, n, x_mean, x_std)

    print(TABLE_HEAD)
    for n in (10, 30, 50):
        net = infer.sample_transitions(cfg, tr.state, val, N_PAST, n, S, bank=tr.bank, sampled=False)
        k = (val.local_quats[:, N_PAST - 1], val.root_pos[:, N_PAST - 1], val.local_quats[:, N_PAST + n],
             val.root_pos[:, N_PAST + n])
        w = tr.gate[1].weight(tr.gate[0].score(keyframe_context(*k, n, val.skeleton, fa)))
        base_q, base_r = slerp_base(*k, n)
        q0, r0 = np.empty(net["q"].shape), np.empty(net["r"].shape)
        for i in range(S):
            qi, ri = gate_blend(net["q"][i:i + 1], net["r"][i:i + 1], base_q, base_r, w)
            q0[i], r0[i] = qi[0], ri[0]
        sq, sr = interpolate_transition(val.local_quats.astype(np.float64), val.root_pos.astype(np.float64),
                                        N_PAST, n)
        slerp_cm = errors(sq[None], sr[None], n)[0][0]
        fb = w < 0.5
        xf, yaw = features(val, n, fa)
        basis = sine_basis(n, a.modes)
        fill_l2p = None

        def report(name, spread_fb, hyp=None, lam=0.0):
            nonlocal fill_l2p
            q, r = q0.copy(), r0.copy()
            if hyp is not None:
                for i in range(1, S):
                    res = np.einsum("nm,bmd->bnd", basis, hyp[:, i - 1]) * (lam * gap_scale(n) * (1 - w))[:, None, None]
                    q[i], r[i] = moved_by(q[i], r[i], res, yaw, lever)
            spread = cfg.timing_spread + (spread_fb - cfg.timing_spread) * (1 - w)
            q, r = bank_sample_blend(tr.bank, *k, q, r, sample_weight(cfg, w), spread, parts)
            cm, l2p = errors(q, r, n)
            fill_l2p = l2p[0] if fill_l2p is None else fill_l2p
            print(f"| {n} | {name} | {l2p.mean() / fill_l2p.mean() - 1:+.1%} "
                  f"| {cm.min(0).mean() / slerp_cm.mean():.3f} | {l2p[:, fb].mean() / fill_l2p[fb].mean() - 1:+.1%} | "
                  f"{cm[:, fb].min(0).mean() / slerp_cm[fb].mean():.3f} ({fb.sum()}) |", flush=True)

        report("shipped", cfg.timing_spread_fallback)
        for eps, (params, mu, sd) in nets.items():
            hyp = np.asarray(mlp(params, (xf.astype(np.float32) - mu) / sd)).reshape(len(xf), S - 1, a.modes, -1)
            for lam in map(float, a.lams.split(",")):
                for fs in map(float, a.fallback_spread.split(",")):
                    report(f"hypotheses eps {eps}, lam {lam}, fallback spread {fs}", fs, hyp, lam)
    print(f"({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
