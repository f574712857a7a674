"""L2P at 30 / 50 frames on every test window of a real-pair source, for interaction runs and the baselines.

    python experiments/interaction_all_windows.py RUN_DIR [RUN_DIR ...] [--source ../shared/data/cmu_pairs] [--ensemble]
        [--members]

The bench's quick mode (what ``make bench`` runs) scores 24 windows per length; this scores all of them (one
sample, true gap and guessed gap, the bench's L2P scale: statistics of the training pairs), and prints each
run's ratio to interpolation with the true / the guessed gap length.  RUN_DIR is a training run (its
validation-selected step) or a shipped weights folder.  ``--ensemble`` adds a row for the mean of the runs'
rollouts (one sample each, own keys); ``--members`` adds a row for every member of an ensemble run
(``model.members`` > 1) alone.  docs/results/interaction.md quotes its output.
"""
import argparse
import sys

LENGTHS = (30, 50)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dirs", nargs="+")
    p.add_argument("--source", default="../shared/data/cmu_pairs")
    p.add_argument("--ensemble", action="store_true", help="also score the mean of the runs' rollouts")
    p.add_argument("--members", action="store_true", help="also score every member of an ensemble run alone")
    args = p.parse_args(argv)
    from inbetween_jax.errors import UserError
    from inbetween_jax.evaluation import interaction as proto
    from inbetween_jax.models.interaction.bench import _model_method, member, windows_l2p
    from inbetween_jax.models.interaction.config import DataConfig
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.models.interaction.infer import load
    from inbetween_jax.models.interaction.probes import fmt, mean_rollout, ratios
    from inbetween_jax.train.run import load_run
    d = DataConfig()
    try:
        pairs = load_pairs(args.source, d.pair_distance)
        trained = [load(load_run(r)) for r in args.run_dirs]
    except (UserError, ValueError, OSError) as e:   # RunError is a ValueError
        print(f"interaction_all_windows: {e}", file=sys.stderr)
        return 2
    train, test = split_pairs(pairs, "train", d.split), split_pairs(pairs, "test", d.split)
    stats = proto.l2p_stats(train, d.pos_scale)
    windows = proto.table1_windows(test, d.pos_scale, 10 ** 6, LENGTHS)
    row = lambda method: windows_l2p(method, windows, stats, d.n_pred, LENGTHS)  # noqa: E731
    interp, guessed = row(proto.interpolation_method), row(proto.guessed_interpolation_method)
    print(f"windows: {' / '.join(str(len(windows[L]['x'])) for L in LENGTHS)} at {' / '.join(map(str, LENGTHS))} "
          f"frames; interpolation, true gap: {fmt(interp)}; guessed gap: {fmt(guessed)}")
    rows = [(f"{name} (step {t.step})", _model_method(t), _model_method(t, gap="guess"))
            for name, t in zip(args.run_dirs, trained)]
    if args.ensemble:
        rows.append((f"mean of {len(rows)} runs", mean_rollout([r[1] for r in rows]),
                     mean_rollout([r[2] for r in rows])))
    if args.members:
        for name, t in zip(args.run_dirs, trained):
            alone = [member(t, i) for i in range(t.cfg.model.members)] if t.cfg.model.members > 1 else []
            rows += [(f"{name} (step {t.step}), member {i} alone", _model_method(m), _model_method(m, gap="guess"))
                     for i, m in enumerate(alone)]
    for name, true_method, guess_method in rows:
        true_gap, guess = row(true_method), row(guess_method)
        print(f"{name}: true gap {fmt(true_gap)} ({ratios(true_gap, interp, 3)}x); "
              f"guessed gap {fmt(guess)} ({ratios(guess, guessed, 3)}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
