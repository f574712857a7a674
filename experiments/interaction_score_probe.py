"""What the interaction score responds to: ground truth degraded in known ways, next to trained models.

    python experiments/interaction_score_probe.py [RUN_DIR[@STEP] ...] [--source ../shared/data/cmu_pairs]
        [--steps 400]

Trains the bench's interaction classifier (``--steps``; the bench's own count by default) on the training takes,
then scores every 40-, 60- and 80-frame test window (the bench's interaction columns) of: ground truth; ground
truth low-pass filtered in time (a Gaussian of 1, 2 and 4 frames); ground truth blended with interpolation;
interpolation; holding the last frame; and each RUN_DIR (a training run at its validation-selected step or at
``@STEP``, or a shipped weights folder; ensembles also as their first member alone).  Beside each score: the mean
joint speed and its standard deviation over time (cm per frame), so a reader can see whether a model loses the
score to damped motion.  Also prints L2P at 30 / 50 frames (every window) for the runs with latent scales 0 and 1,
to show whether the latent carries anything.  docs/results/interaction.md quotes its output.
"""
import argparse
import sys
import time

import numpy as np

LENGTHS = (40, 60, 80)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dirs", nargs="*")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    p.add_argument("--steps", type=int, default=None, help="classifier steps (default: the bench's)")
    args = p.parse_args(argv)
    from inbetween_jax.errors import UserError
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bench import CLASSIFIER_STEPS, _model_method, member, windows_l2p
    from inbetween_jax.models.interaction.config import DataConfig, get_config
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.interaction.probes import fmt, rollout, run_and_step, score_windows, truth_variants
    from inbetween_jax.train.run import load_run
    t0, d = time.time(), DataConfig()
    try:
        pairs = load_pairs(args.source, d.pair_distance)
        trained = [load(load_run(*run_and_step(r))) for r in args.run_dirs]
    except (UserError, ValueError, OSError) as e:   # RunError is a ValueError
        print(f"interaction_score_probe: {e}", file=sys.stderr)
        return 2
    train, test = split_pairs(pairs, "train", d.split), split_pairs(pairs, "test", d.split)
    steps = CLASSIFIER_STEPS if args.steps is None else args.steps
    joints = trained[0].cfg.model.pjd_joints if trained else get_config().model.pjd_joints
    gdef, params, acc = proto.train_classifier(train, pairs[0].feats.shape[2], joints, steps=steps,
                                               pos_scale=d.pos_scale)
    windows = proto.table1_windows(test, d.pos_scale, 128, LENGTHS)
    print(f"classifier: {steps} steps, final batch accuracy {acc:.2f}; windows "
          f"{' / '.join(str(len(windows[L]['x'])) for L in LENGTHS)} at {' / '.join(map(str, LENGTHS))} frames")
    rows = truth_variants()
    for name, t in zip(args.run_dirs, trained):
        rows[f"{name} (step {t.step})"] = rollout(_model_method(t))
        if t.bank is not None:
            rows[f"{name}, network alone (motion bank off)"] = rollout(_model_method(t, use_bank=False))
        if t.cfg.model.members > 1:
            rows[f"{name}, first member alone"] = rollout(_model_method(member(t)))
    print("| method | score 40 / 60 / 80 | x ground truth | speed (cm/frame) | speed std over time |\n"
          "|---|---|---|---|---|")
    ref = None
    for name, make in rows.items():
        score, speed, spread = score_windows(gdef, params, windows, make, d.pos_scale)
        ref = np.mean(score) if ref is None else ref
        print(f"| {name} | {fmt(score, 2)} | {np.mean(score) / ref:.2f} | {speed:.2f} | {spread:.2f} |", flush=True)
    if trained:
        stats = proto.l2p_stats(train, d.pos_scale)
        l2p_windows = proto.table1_windows(test, d.pos_scale, 10 ** 6, (30, 50))
        for name, t in zip(args.run_dirs, trained):
            for scale in (0.0, 1.0):
                l2p = windows_l2p(_model_method(t, latent_scale=scale), l2p_windows, stats, d.n_pred, (30, 50))
                print(f"{name}: latent scale {scale:g}, L2P 30 / 50 (every window) {fmt(l2p)}")
    print(f"{time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
