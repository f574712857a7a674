"""Can the validation take tell the interaction model's worst windows apart?  Three probes, validation take only.

    python experiments/interaction_tail_probe.py RUN_DIR [--source ../shared/data/cmu_pairs] [--caps 0,0.8]

1. **Sharper base-error prediction.** ``model.departure_cap`` bounds a window's ratio by ``1 + c * predicted /
   actual`` interpolation error, so a better prediction of interpolation's error tightens it.  Per feature set, a
   log-linear least-squares fit on the ``fit`` takes' windows (interpolation alone; the shipped set is the first)
   and its R^2 / residual sd (log) on the fit takes and on the validation take.
2. **Per-character gate and cap.**  The shipped gate gives both dancers one weight from their mean speed, and one
   cap from the window's departure.  Here each dancer gets its own: a speed score from its own joint speed and a cap
   from its own departure over the prediction on its own features.  A window's error is the mean of its two
   dancers' errors, so each dancer's error is measured at every blend weight and interpolated between them.  The
   thresholds are chosen by :func:`~inbetween_jax.models.ood.calibrate_gate`'s rule for every variant.
3. **Shrinking by the members' spread.**  The gate's weight also multiplied by ``1 / (1 + a (s / D)^2)``, with
   ``s`` the ensemble members' mean distance from their mean fill and ``D`` the fill's departure from
   interpolation: where the members disagree about a departure, keep less of it.

Each row: per-window ratio to interpolation (one sample, true gap), mean / p90 / max at 30, 50 frames and pooled.
"""
import argparse
import dataclasses

import numpy as np


def summary(r) -> str:
    return f"{r.mean():.3f} / {np.quantile(r, 0.9):.3f} / {r.max():.3f}"


def extra_features(ctx, keypose, L) -> dict:
    """Candidate (B,) log features beyond :func:`~inbetween_jax.models.interaction.gate.base_error_features`."""
    c, k = np.asarray(ctx, np.float64)[..., :3], np.asarray(keypose, np.float64)[..., :3]
    last, v = c[:, :, -1], c[:, :, -1] - c[:, :, -2]
    cm = lambda x: np.log(100.0 * x + 0.1)                                   # noqa: E731
    return {"velocity mismatch |v (L+1) - (key - last)|": cm(np.linalg.norm(v * (L + 1) - (k - last), axis=-1).mean((1, 2))),
            "acceleration at the last frame": cm(np.linalg.norm(c[:, :, -1] - 2 * c[:, :, -2] + c[:, :, -3],
                                                                axis=-1).mean((1, 2))),
            "path length over the last 10 frames": cm(np.linalg.norm(np.diff(c[:, :, -10:], axis=2), axis=-1)
                                                      .sum(2).mean((1, 2))),
            "median joint speed": cm(np.median(np.linalg.norm(v, axis=-1).reshape(len(c), -1), 1)),
            "context travel (first to last frame)": cm(np.linalg.norm(c[:, :, -1] - c[:, :, 0], axis=-1).mean((1, 2)))}


def feature_probe(fit, val, d, lengths) -> None:
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.gate import base_error_features, fit_base_error, interpolation_base
    from inbetween_jax.models.interaction.samples import window_errors_cm
    data = {}
    for name, pairs, n in (("fit", fit, 400), ("val", val, 10_000)):
        F, X, E = [], [], []
        for L, b in proto.table1_windows(pairs, d.pos_scale, n, lengths).items():
            ctx = b["x"][:, :, :proto.N_INPUT]
            F.append(base_error_features(ctx, b["keypose"], L))
            X.append(extra_features(ctx, b["keypose"], L))
            E.append(window_errors_cm(interpolation_base(ctx, b["keypose"], L), b))
        extra = {k: np.concatenate([x[k] for x in X]) for k in X[0]}
        data[name] = (np.concatenate(F), extra, np.concatenate(E))                 # errors in cm
    sets = [("shipped: 1, log gap, log speed, log keypose distance", [])] + [(f"+ {k}", [k]) for k in data["fit"][1]]
    sets.append(("+ all of them", list(data["fit"][1])))
    print(f"1. interpolation's error from the context: {len(data['fit'][2])} fit / {len(data['val'][2])} val windows")
    print("| features | fit R^2 / sd | val R^2 / sd |\n|---|---|---|")
    for label, keys in sets:
        A = {s: np.c_[data[s][0], *[data[s][1][k] for k in keys]] for s in data}
        coef = fit_base_error(A["fit"], data["fit"][2])          # the shipped fit, on more features
        cells = []
        for s in ("fit", "val"):
            log_err = np.log(np.maximum(data[s][2], 1e-6))
            r = log_err - A[s] @ coef
            cells.append(f"{1 - r.var() / log_err.var():.3f} / {r.std():.3f}")
        print(f"| {label} | " + " | ".join(cells) + " |")


def gated_probe(tr, val, d, lengths, caps, coef) -> None:
    import jax
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bank import ease_into_keypose
    from inbetween_jax.models.interaction.bench import _model_method, member
    from inbetween_jax.models.interaction.gate import (departure_cm, gate_blend, interpolation_base,
                                                       predicted_base_error_cm)
    from inbetween_jax.models.interaction.samples import _common, _truth
    from inbetween_jax.models.ood import BLEND_WEIGHTS, Gate
    m = tr.cfg.model
    plain = dataclasses.replace(tr, gate=None, cfg=dataclasses.replace(tr.cfg, model=dataclasses.replace(
        m, ease_frames=0, ood_gate=False)))
    R = {k: [] for k in ("err", "ierr", "speed", "dep", "pred_char", "pred_win", "spread", "L")}
    for L, b in proto.table1_windows(val, d.pos_scale, 64, lengths).items():
        ctx, kp, gaps = b["x"][:, :, :proto.N_INPUT], b["keypose"], np.full(len(b["x"]), L)
        steps = -(-L // d.n_pred)
        learned = np.asarray(_model_method(plain)(b, steps, 1, jax.random.key(L)))[:, :, :, :L]
        members = [np.asarray(_model_method(member(plain, i))(b, steps, 1, jax.random.key(L)))[0, :, :, :L]
                   for i in range(m.members)]
        base, truth = interpolation_base(ctx, kp, L), _truth(b, L)
        per_char = lambda y: 100 * np.linalg.norm(_common(y, b) - truth, axis=-1).mean((2, 3))   # noqa: E731
        R["err"].append(np.stack([per_char(ease_into_keypose(gate_blend(learned, base, np.full(len(gaps), w)), kp,
                                                             gaps, m.ease_frames)[0]) for w in BLEND_WEIGHTS], -1))
        R["ierr"].append(per_char(base))
        c = np.asarray(ctx, np.float64)[..., :3]
        R["speed"].append(100 * np.linalg.norm(c[:, :, -1] - c[:, :, -2], axis=-1).mean(-1))
        R["dep"].append(100 * np.linalg.norm(learned[0, ..., :3] - base[..., :3], axis=-1).mean((2, 3)))
        R["pred_char"].append(np.stack([predicted_base_error_cm(coef, np.repeat(np.asarray(ctx)[:, [i]], 2, 1),
                                                                np.repeat(np.asarray(kp)[:, [i]], 2, 1), L)
                                        for i in range(2)], 1))
        R["pred_win"].append(predicted_base_error_cm(coef, ctx, kp, L))
        mean_fill = np.mean(members, 0)
        R["spread"].append(np.mean([departure_cm(x, mean_fill) for x in members], 0))
        R["L"].append(gaps)
    err, ierr, speed, dep, pc, pw, spread, L = (np.concatenate(R[k]) for k in R)
    base_cm = ierr.mean(1)

    def ratio(w_a, w_b):
        at = lambda w, ch: np.array([np.interp(x, BLEND_WEIGHTS, e) for x, e in zip(w, err[:, ch])])  # noqa: E731
        return (at(w_a, 0) + at(w_b, 1)) / 2 / base_cm

    def choose(weights_of, scores):
        """calibrate_gate's rule over (lo, hi) candidates, for weights per dancer."""
        qs = np.quantile(np.ravel(scores), [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0])
        best = None
        for lo, hi in [(q, q * f) for q in qs for f in (1.0001, 1.1, 1.25, 1.5, 2.0, 3.0)] + [(np.inf, np.inf)]:
            r = ratio(*weights_of(Gate(float(lo), float(hi), enabled=np.isfinite(lo))))
            ok = (np.quantile(r, 0.9) <= 1.05 + 1e-9 and r.max() <= 1.5 + 1e-9
                  and all(r[L == g].mean() <= 1 + 1e-9 for g in lengths))
            key = (0 if ok else 1, r.mean() if ok else np.quantile(r, 0.9))
            if best is None or key < best[0]:
                best = (key, r)
        return best[1]

    cap = lambda c, x: np.ones_like(x) if c <= 0 else np.minimum(1.0, c / np.maximum(x, 1e-9))  # noqa: E731
    s_win, s_char = 1 / (1 + speed.mean(1)), 1 / (1 + speed)
    dep_win, rel = dep.mean(1) / pw, spread / np.maximum(dep.mean(1), 1e-9)
    print(f"\n2.-3. gated, validation take ({len(L)} windows) | "
          + " | ".join(f"{g}: mean / p90 / max" for g in lengths) + " | pooled |")
    rows = []
    for c in caps:
        rows.append((f"one weight per window (shipped form), cap {c}", lambda g, c=c: (
            g.weight(s_win) * cap(c, dep_win),) * 2, s_win))
        rows.append((f"a weight per dancer (gate and cap), cap {c}", lambda g, c=c: (
            g.weight(s_char[:, 0]) * cap(c, dep[:, 0] / pc[:, 0]), g.weight(s_char[:, 1]) * cap(c, dep[:, 1] / pc[:, 1])),
            s_char))
        rows.append((f"a gate weight per dancer, one cap per window, cap {c}", lambda g, c=c: (
            g.weight(s_char[:, 0]) * cap(c, dep_win), g.weight(s_char[:, 1]) * cap(c, dep_win)), s_char))
        for a in (1.0, 4.0):
            rows.append((f"shipped form x member-spread shrink a={a:g}, cap {c}", lambda g, c=c, a=a: (
                g.weight(s_win) * cap(c, dep_win) / (1 + a * rel ** 2),) * 2, s_win))
    for label, weights_of, scores in rows:
        r = choose(weights_of, scores)
        print(f"| {label} | " + " | ".join(summary(r[L == g]) for g in lengths) + f" | {summary(r)} "
              f"(mean {r.mean():.5f}) |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    p.add_argument("--caps", default="0,0.8")
    a = p.parse_args()
    import os
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.gate import BASE_ERROR_KEY
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.ood import OOD_FILE
    from inbetween_jax.train.run import load_run
    tr = load(load_run(a.run_dir), with_gate=False)
    d, lengths = tr.cfg.data, (30, 50)
    pairs = load_pairs(a.source, d.pair_distance)
    fit, val = (split_pairs(pairs, s, tuple(d.split)) for s in ("fit", "val"))
    feature_probe(fit, val, d, lengths)
    coef = np.load(os.path.join(a.run_dir, OOD_FILE))[BASE_ERROR_KEY]
    gated_probe(tr, val, d, lengths, [float(c) for c in a.caps.split(",")], coef)


if __name__ == "__main__":
    main()
