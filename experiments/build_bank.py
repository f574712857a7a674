"""Write an interaction run's motion bank (:mod:`inbetween_jax.models.interaction.bank`) and turn it on.

    python experiments/build_bank.py RUN_DIR [--source DIR] [--split fit] [--set model.bank_k=8 ...]

Builds the bank from the ``--split`` pairs (default ``fit``: the training takes without the validation take, so
bank settings chosen on the validation take never saw it; the test takes are refused) of ``--source`` (default:
the run's own data source), writes ``RUN_DIR/bank.npz`` and applies the ``--set`` inference switches
(``model.bank_k``, ``model.bank_weight``, ``model.texture_sigma``, ``model.texture_gain``) to
``RUN_DIR/run.json``.  RUN_DIR is a training run or a shipped weights folder.
"""
from __future__ import annotations

import argparse
import json
import os
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir", metavar="RUN_DIR")
    ap.add_argument("--source", default=None, help="paired data folder (default: the run's data source)")
    ap.add_argument("--split", default="fit", choices=("fit", "train"), help="pairs the bank holds")
    ap.add_argument("--set", dest="switches", action="append", default=[], metavar="KEY=VALUE",
                    help="bank switch written into run.json, e.g. model.bank_k=8 (repeatable)")
    a = ap.parse_args(argv)
    from inbetween_jax.errors import UserError
    from inbetween_jax.models.interaction.bank import BANK_FILE, SWITCHES, MotionBank
    from inbetween_jax.models.interaction.config import Config
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.shipped import _with_overrides
    from inbetween_jax.train.config import config_from_dict
    from inbetween_jax.train.run import RUN_FILE, RunError, load_run
    try:
        run = load_run(a.run_dir, need_checkpoint=False)
        if run.model != "interaction":
            raise RunError(f"{a.run_dir}: holds a {run.model} run, not an interaction run")
        bad = [s for s in a.switches if s.split("=", 1)[0] not in SWITCHES]
        if bad:
            raise RunError(f"--set {bad[0]}: not a bank switch (choose {', '.join(SWITCHES)})")
        cfg = config_from_dict(Config, run.config)
        source = a.source or run.data.get("source")
        pairs = split_pairs(load_pairs(source, cfg.data.pair_distance), a.split, cfg.data.split)
        J = int(run.extra["num_joints"])
        if pairs and pairs[0].feats.shape[2] != J:
            raise UserError(f"{source}: {pairs[0].feats.shape[2]} joints, the run has {J}")
        bank = MotionBank.from_pairs(pairs, cfg.data.pos_scale)
        path = os.path.join(a.run_dir, RUN_FILE)
        with open(path) as f:
            meta = json.load(f)
        if a.switches:
            meta["config"] = _with_overrides("interaction", meta["config"], a.switches)
        meta["bank"] = {"source": source, "split": a.split, "takes": list(bank.names), "frames": bank.num_frames,
                       "switches": list(a.switches) or meta.get("bank", {}).get("switches", [])}
    except (UserError, RunError, ValueError, OSError) as e:
        print(f"build_bank: error: {e}", file=sys.stderr)
        return 2
    bank.save(os.path.join(a.run_dir, BANK_FILE))
    with open(path + ".tmp", "w") as f:
        json.dump(meta, f, indent=1)
    os.replace(path + ".tmp", path)
    size = os.path.getsize(os.path.join(a.run_dir, BANK_FILE)) / 2 ** 20
    print(f"{a.run_dir}/{BANK_FILE}: {len(bank.takes)} takes ({', '.join(bank.names)}), {bank.num_frames} frames, "
          f"{size:.2f} MB; switches: {' '.join(a.switches) or 'unchanged'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
