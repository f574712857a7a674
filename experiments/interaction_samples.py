"""The interaction model's samples on the validation take: how much they differ and how real each one looks.

    python experiments/interaction_samples.py RUN_DIR [--source ../shared/data/cmu_pairs] [--try SWITCHES ...]
        [--samples 10] [--test]

For the run as configured and each ``--try`` (comma-separated bank switches, e.g.
``model.bank_sample_weight=0.5``): the samples table (``inbetween_jax.models.interaction.samples``) at 30 / 50
frames, true gap.  The classifier is the bench's (its step count) trained on the ``fit`` takes, so the validation
take is new to it as to the network and the bank.  ``--test`` judges the test takes instead (classifier on the
training takes, as the bench): look once, after choosing.
"""
import argparse
import dataclasses

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    p.add_argument("--try", dest="tries", action="append", default=[], metavar="SWITCHES")
    p.add_argument("--samples", type=int, default=10)
    p.add_argument("--test", action="store_true", help="the test takes (look once)")
    a = p.parse_args()
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bench import CLASSIFIER_STEPS, _model_method
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.interaction.probes import parse_try
    from inbetween_jax.models.interaction.samples import sample_table
    from inbetween_jax.train.run import load_run
    tr = load(load_run(a.run_dir))
    d = tr.cfg.data
    pairs = load_pairs(a.source, d.pair_distance)
    train = split_pairs(pairs, "train" if a.test else "fit", tuple(d.split))
    judged = split_pairs(pairs, "test" if a.test else "val", tuple(d.split))
    cls = proto.train_classifier(train, train[0].feats.shape[2], tr.cfg.model.pjd_joints, steps=CLASSIFIER_STEPS,
                                 pos_scale=d.pos_scale)
    windows = proto.table1_windows(judged, d.pos_scale, 128, (30, 50))
    stats = proto.l2p_stats(train, d.pos_scale)
    print(f"{'test takes' if a.test else 'validation take'}: {', '.join(x.name for x in judged)}; "
          f"{a.samples} samples; classifier accuracy {cls[2]:.2f}")
    print("| setting | frames | fill (sample 0) L2P / interp | mean-of-N L2P / interp | best-of-N / interp | APD (m) "
          "| pairwise (cm) | score / ground truth's |\n|---|---|---|---|---|---|---|---|")
    for text in [""] + a.tries:
        run = dataclasses.replace(tr, cfg=dataclasses.replace(tr.cfg, model=parse_try(text, tr.cfg.model)))
        for r in sample_table(_model_method(run), windows, stats, cls[:2], a.samples):
            print(f"| {text or 'as configured'} | {r['frames']} | {r['fill_l2p'] / r['interp_l2p']:.3f} | "
                  f"{r['mean_l2p'] / r['interp_l2p']:.3f} | "
                  f"{r['best_l2p'] / r['interp_l2p']:.3f} | {r['apd_m']:.3f} | {r['pairwise_cm']:.2f} | "
                  f"{r['score'] / r['score_gt']:.3f} |", flush=True)


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
