"""Motion-bank switches of an interaction run, scored on the validation take (or the test takes).

    python experiments/interaction_bank_probe.py RUN_DIR [--split val] [--source ../shared/data/cmu_pairs]
        [--score] --try model.bank_k=8,model.bank_weight=0.5 [--try ...]

Builds the motion bank of the ``fit`` takes in memory (as ``inbetween build-bank`` does, so the validation
take is never in it), then for the network alone and for every ``--try`` (comma-separated inference switches of
:data:`inbetween_jax.models.interaction.bank.SWITCHES`, applied on top of the run's own) prints L2P at 30 / 50
frames on every window of ``--split`` as a ratio to interpolation with the true gap, and with a guessed gap as a
ratio to the guessed-length interpolation; ``--score`` adds the interaction score (the bench's classifier, trained
on the training takes) on every 40 / 60 / 80-frame window, as a multiple of ground truth's.  Bank switches are
chosen on ``--split val``; ``--split test`` reports what the chosen ones give.  docs/results/interaction.md quotes
its output.
"""
import argparse
import dataclasses
import sys
import time

L2P_LENGTHS = (30, 50)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    p.add_argument("--split", default="val", choices=("val", "test"))
    p.add_argument("--score", action="store_true", help="also the interaction score (trains the classifier)")
    p.add_argument("--try", dest="tries", action="append", default=[], metavar="KEY=VALUE,...")
    args = p.parse_args(argv)
    from inbetween_jax.errors import UserError
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bank import MotionBank
    from inbetween_jax.models.interaction.bench import CLASSIFIER_STEPS, _model_method, windows_l2p
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.interaction.probes import classifier_scorer, fmt, parse_try, ratios
    from inbetween_jax.train.run import load_run
    t0 = time.time()
    try:
        trained = load(load_run(args.run_dir))
        d = trained.cfg.data
        pairs = load_pairs(args.source, d.pair_distance)
        fit, judged = split_pairs(pairs, "fit", d.split), split_pairs(pairs, args.split, d.split)
        bank = MotionBank.from_pairs(fit, d.pos_scale)
        variants = [("the network alone", dataclasses.replace(trained, bank=None))]
        variants += [(t, dataclasses.replace(trained, bank=bank, cfg=dataclasses.replace(
            trained.cfg, model=parse_try(t, trained.cfg.model)))) for t in args.tries]
    except (UserError, ValueError, OSError) as e:   # RunError is a ValueError
        print(f"interaction_bank_probe: {e}", file=sys.stderr)
        return 2
    windows = proto.table1_windows(judged, d.pos_scale, 10 ** 6, L2P_LENGTHS)
    train = split_pairs(pairs, "train", d.split)
    # L2P scale as checkpoint selection (validation: the fit takes) and the bench (test: the training takes) set it
    stats = proto.l2p_stats(fit if args.split == "val" else train, d.pos_scale)
    row = lambda method: windows_l2p(method, windows, stats, d.n_pred, L2P_LENGTHS)  # noqa: E731
    interp, guessed = row(proto.interpolation_method), row(proto.guessed_interpolation_method)
    score = (classifier_scorer(train, judged, trained.cfg.model.pjd_joints, d, CLASSIFIER_STEPS) if args.score
             else None)
    print(f"{args.split} windows {' / '.join(str(len(windows[L]['x'])) for L in L2P_LENGTHS)} at "
          f"{' / '.join(map(str, L2P_LENGTHS))} frames; interpolation {fmt(interp)} (true gap), "
          f"{fmt(guessed)} (guessed)")
    print("| switches | L2P 30 / 50, true gap (x interpolation) | gap guessed (x guessed-length interpolation) |"
          + (" score x ground truth |" if score else ""))
    print("|---|---|---|" + ("---|" if score else ""))
    for name, t in variants:
        true_gap, guess = row(_model_method(t)), row(_model_method(t, gap="guess"))
        print(f"| {name} | {ratios(true_gap, interp)} | {ratios(guess, guessed)} |"
              + (f" {score(_model_method(t)):.2f} |" if score else ""), flush=True)
    print(f"{time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
