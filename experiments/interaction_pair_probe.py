"""What the interaction classifier marks down in the sampled mode's captured windows: the partner's placement.

    python experiments/interaction_pair_probe.py [RUN_DIR] [--source ../shared/data/cmu_pairs] [--k 9]

On the validation take (classifier trained on the ``fit`` takes, the bench's step count), 30 / 50-frame windows:

1. Ground truth moved in known ways, scored as a multiple of ground truth's: both dancers sliding over the floor
   together (a horizontal offset rising and falling over the gap, ``sin(pi t)``, one random direction per
   window), one dancer sliding, every joint moved on its own, one dancer turned about its root, the gap retimed.
2. The ``k`` nearest bank windows of each query (``RUN_DIR``'s bank and match, default the shipped weights), whole
   (weight 1): as captured, warped onto the query's ends (``bank._warped_mean``), and both scored once with the
   query's placement of the two dancers (what the package does: each dancer lives in its own keyframe space) and
   once with the bank pair's own.
3. The same windows retrieved with the pair's placement at the keyframe in the match (``model.bank_pair_weight``
   W), warped per dancer or with dancer B warped in dancer A's keyframe space: score, mean and best-of-k joint
   error (cm), and how far the retrieved pairs stand from the query's placement (:func:`bank.pair_features`).

docs/results/interaction.md ("The partner's placement") quotes its output.  Measures only; chooses nothing.
"""
import argparse
import time

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir", nargs="?", default="inbetween_jax/assets/weights/interaction")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    p.add_argument("--k", type=int, default=9)
    a = p.parse_args()
    import jax.numpy as jnp

    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.evaluation.interaction import N_INPUT as N, classify_windows
    from inbetween_jax.models.interaction import bank as bk
    from inbetween_jax.models.interaction.bench import CLASSIFIER_STEPS
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.features import keyframe_sample, to_common_space, to_space
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.interaction.probes import score_windows
    from inbetween_jax.models.interaction.samples import window_errors_cm
    from inbetween_jax.train.run import load_run
    t0 = time.time()
    tr = load(load_run(a.run_dir))
    d, bank = tr.cfg.data, tr.bank
    pairs = load_pairs(a.source, d.pair_distance)
    fit, val = split_pairs(pairs, "fit", tuple(d.split)), split_pairs(pairs, "val", tuple(d.split))
    gdef, params, _ = proto.train_classifier(fit, pairs[0].feats.shape[2], tr.cfg.model.pjd_joints,
                                             steps=CLASSIFIER_STEPS, pos_scale=d.pos_scale)
    windows = proto.table1_windows(val, d.pos_scale, 128, (30, 50))
    rng = np.random.default_rng(0)

    def gt(b, L):
        return b["x"][:, :, N:N + L]

    def bump(L):
        return np.sin(np.pi * np.arange(1, L + 1) / (L + 1))[None, None, :, None, None]

    def slide(metres, who):                   # who: (A, B) multipliers; one horizontal direction per window
        def make(b, L):
            x = gt(b, L).copy()
            u = rng.normal(size=(len(x), 1, 1, 1, 3)) * np.array([1.0, 0.0, 1.0])
            u = u / np.linalg.norm(u, axis=-1, keepdims=True)
            x[..., :3] += metres * np.reshape(who, (1, 2, 1, 1, 1)) * u * bump(L)
            return x
        return make

    def joints(metres):
        def make(b, L):
            x = gt(b, L).copy()
            u = rng.normal(size=(len(x), 2, 1, x.shape[3], 3))
            x[..., :3] += metres * u / np.linalg.norm(u, axis=-1, keepdims=True) * bump(L)
            return x
        return make

    def turn_b(degrees):
        def make(b, L):
            x = gt(b, L).copy()
            ang = np.deg2rad(degrees) * bump(L)[:, 0, :, 0, 0] * rng.choice([-1.0, 1.0], size=(len(x), 1))  # (B, L)
            c, s = np.cos(ang)[..., None], np.sin(ang)[..., None]

            def rot(v):
                out = v.copy()
                out[..., 0], out[..., 2] = c * v[..., 0] + s * v[..., 2], -s * v[..., 0] + c * v[..., 2]
                return out
            root = x[:, 1, :, :1, :3]
            x[:, 1, :, :, :3] = rot(x[:, 1, :, :, :3] - root) + root
            x[:, 1, :, :, 3:6], x[:, 1, :, :, 6:9] = rot(x[:, 1, :, :, 3:6]), rot(x[:, 1, :, :, 6:9])
            return x
        return make

    def retimed(amount):
        def make(b, L):
            full = b["x"][:, :, N - 1:N + L + 1]
            u = (np.arange(1, L + 1) / (L + 1) + amount * np.sin(np.pi * np.arange(1, L + 1) / (L + 1)) / np.pi)
            u = u * (L + 1)
            i = np.floor(u).astype(int)
            w = (u - i)[None, None, :, None, None]
            return full[:, :, i] * (1 - w) + full[:, :, np.minimum(i + 1, L + 1)] * w
        return make

    rows = {"ground truth": gt}
    rows.update({f"both dancers slide together, {m} m": slide(m, (1, 1)) for m in (0.15, 0.3, 0.6)})
    rows.update({f"dancer B slides, {m} m": slide(m, (0, 1)) for m in (0.15, 0.3)})
    rows.update({f"every joint moved on its own, {m} m": joints(m) for m in (0.05, 0.1)})
    rows.update({f"dancer B turned, {g} degrees": turn_b(g) for g in (20, 45, 90)})
    rows.update({f"retimed, {r}": retimed(r) for r in (0.3, 0.6)})
    print("1. ground truth moved in known ways (validation take; score 30 / 50 frames, x ground truth's)\n\n"
          "| ground truth ... | score 30 / 50 | x ground truth's |\n|---|---|---|")
    ref = None
    for name, make in rows.items():
        score = score_windows(gdef, params, windows, make, d.pos_scale)[0]
        ref = np.mean(score) if ref is None else ref
        print(f"| {name} | {score[0]:.3f} / {score[1]:.3f} | {np.mean(score) / ref:.3f} |", flush=True)

    def common(x, R, t):
        return np.asarray(to_common_space(jnp.asarray(np.asarray(x, np.float32)), R, t))

    def scores(pred, b, R=None, t=None):
        """(B, W) classifier scores of the last context frame + pred, dancer B placed by (R, t) (default the
        query's)."""
        R, t = (b["rel_R"], b["rel_t"]) if R is None else (R, t)
        clip = np.concatenate([common(b["x"][:, :, N - 1:N], R, t), common(pred, R, t)], 2)
        return np.asarray(classify_windows(gdef, params, jnp.asarray(clip))[0])

    print(f"\n2-3. the {a.k} nearest bank windows, whole (weight 1)\n")
    for L, b in windows.items():
        ctx, kp = b["x"][:, :, :N], b["x"][:, :, N + L]
        ref = scores(gt(b, L), b).mean()
        starts = bank._starts(N, L)
        own = [keyframe_sample(bank.takes[i], s, N + L + 1, N + L, bank.forward_axis) for i, s in starts]
        bank_R = np.stack([o["rel_R"] for o in own]).astype(np.float32)
        bank_t = (np.stack([o["rel_t"] for o in own]) * bank.pos_scale).astype(np.float32)
        base = bk.match_features(ctx, kp)
        d2 = ((base[:, None] - bank.index(N, L)[None]) ** 2).sum(-1)
        pair_d2 = ((bk.pair_features(b["rel_R"], b["rel_t"])[:, None] - bank.pair_index(N, L)[None]) ** 2).sum(-1)
        print(f"{L} frames ({len(ctx)} windows; ground truth's score {ref:.3f})\n\n"
              "| windows | score / ground truth's |\n|---|---|")
        idx = np.argsort(d2, 1)[:, :a.k]
        near = bank.gather(N, L, idx)
        out = {"as captured, query's placement": [], "warped, query's placement (the package's)": [],
               "as captured, the bank pair's own placement": [], "warped, the bank pair's own placement": []}
        for j in range(a.k):
            c, i = near[:, j], idx[:, j]
            warped = bk._warped_mean(c[:, None], ctx, kp, L)
            out["as captured, query's placement"].append(scores(c[:, :, N:N + L], b).mean())
            out["warped, query's placement (the package's)"].append(scores(warped, b).mean())
            out["as captured, the bank pair's own placement"].append(
                scores(c[:, :, N:N + L], b, bank_R[i], bank_t[i]).mean())
            out["warped, the bank pair's own placement"].append(scores(warped, b, bank_R[i], bank_t[i]).mean())
        for name, v in out.items():
            print(f"| {name} | {np.mean(v) / ref:.3f} |")
        print("\n| W (`model.bank_pair_weight`) | warp | score / ground truth's | joint error, mean / best of k (cm) "
              "| placement distance (median) |\n|---|---|---|---|---|")
        for w in (0.0, 3.0, 9.0, 27.0):
            idx = np.argsort(d2 + w ** 2 * pair_d2, 1)[:, :a.k]
            far = np.median(np.sqrt(np.take_along_axis(pair_d2, idx, 1)))
            near = bank.gather(N, L, idx)                                     # (B, k, 2, N + L + 1, J, 9)
            for mode in ("per dancer", "B in A's space"):
                sc, err = [], []
                for j in range(a.k):
                    c, i = near[:, j], idx[:, j]
                    if mode == "per dancer":
                        warped = bk._warped_mean(c[:, None], ctx, kp, L)
                    else:                   # the pair warped together in A's space, then B back into its own
                        q_ctx = common(ctx, b["rel_R"], b["rel_t"])
                        q_kp = common(kp[:, :, None], b["rel_R"], b["rel_t"])[:, :, 0]
                        wc = bk._warped_mean(common(c, bank_R[i], bank_t[i])[:, None], q_ctx, q_kp, L)
                        warped = wc.copy()
                        warped[:, 1] = to_space(wc[:, 1], b["rel_R"][:, 1][:, None], b["rel_t"][:, 1][:, None])
                    sc.append(scores(warped, b).mean())
                    err.append(window_errors_cm(warped, b))
                err = np.stack(err)
                print(f"| {w:g} | {mode} | {np.mean(sc) / ref:.3f} | {err.mean():.1f} / {err.min(0).mean():.1f} | "
                      f"{far:.2f} |", flush=True)
        print()
    print(f"{time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
