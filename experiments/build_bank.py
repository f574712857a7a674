"""Write a run's motion bank and turn it on: an interaction run's (:mod:`inbetween_jax.models.interaction.bank`)
or an S-CVAE run's (:mod:`inbetween_jax.models.scvae.bank`).

    python experiments/build_bank.py RUN_DIR [--source DIR] [--split fit] [--mirror] [--set model.bank_k=8 ...]

Builds the bank from the ``--split`` motions (default ``fit``: the training files or takes without the
validation ones, so bank settings chosen on the validation split never saw it; the test files are never in it)
of ``--source`` (default: the run's own data source), writes ``RUN_DIR/bank.npz`` and applies the ``--set``
inference switches (interaction: ``model.bank_k``, ``model.bank_weight``, ``model.texture_sigma``,
``model.texture_gain``; S-CVAE: ``model.bank_k``, ``model.bank_weight``, ``model.bank_tau``) to
``RUN_DIR/run.json``.  ``--mirror`` (S-CVAE banks): the bank holds each motion's left-right mirror image too
(twice the transitions and the file size).  RUN_DIR is a training run or a shipped weights folder.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir", metavar="RUN_DIR")
    ap.add_argument("--source", default=None, help="paired data folder (default: the run's data source)")
    ap.add_argument("--split", default="fit", choices=("fit", "train"), help="pairs the bank holds")
    ap.add_argument("--mirror", action="store_true", help="S-CVAE: add each motion's mirror image to the bank")
    ap.add_argument("--set", dest="switches", action="append", default=[], metavar="KEY=VALUE",
                    help="bank switch written into run.json, e.g. model.bank_k=8 (repeatable)")
    a = ap.parse_args(argv)
    from inbetween_jax.errors import UserError
    from inbetween_jax.shipped import _with_overrides
    from inbetween_jax.train.run import RUN_FILE, RunError, load_run
    try:
        run = load_run(a.run_dir, need_checkpoint=False)
        if run.model not in BUILDERS:
            raise RunError(f"{a.run_dir}: holds a {run.model} run; banks exist for {', '.join(BUILDERS)} runs")
        module = importlib.import_module(f"inbetween_jax.models.{run.model}.bank")
        switches, file_name = module.SWITCHES, module.BANK_FILE
        bad = [s for s in a.switches if s.split("=", 1)[0] not in switches]
        if bad:
            raise RunError(f"--set {bad[0]}: not a bank switch (choose {', '.join(switches)})")
        if a.mirror and run.model != "scvae":
            raise RunError(f"--mirror: S-CVAE banks only ({a.run_dir} holds a {run.model} run)")
        source = a.source or run.data.get("source")
        bank = BUILDERS[run.model](run, source, a.split, a.mirror)
        path = os.path.join(a.run_dir, RUN_FILE)
        with open(path) as f:
            meta = json.load(f)
        if a.switches:
            meta["config"] = _with_overrides(run.model, meta["config"], a.switches)
        meta["bank"] = {"source": source, "split": a.split, "mirror": a.mirror, "takes": list(bank.names),
                        "frames": bank.num_frames,
                        "switches": list(a.switches) or meta.get("bank", {}).get("switches", [])}
    except (UserError, RunError, ValueError, OSError) as e:
        print(f"build_bank: error: {e}", file=sys.stderr)
        return 2
    bank.save(os.path.join(a.run_dir, file_name))
    with open(path + ".tmp", "w") as f:
        json.dump(meta, f, indent=1)
    os.replace(path + ".tmp", path)
    size = os.path.getsize(os.path.join(a.run_dir, file_name)) / 2 ** 20
    names = ", ".join(bank.names) if len(bank.names) <= 12 else f"{', '.join(bank.names[:3])}, ..."
    print(f"{a.run_dir}/{file_name}: {len(bank.names)} clips ({names}), {bank.num_frames} frames, "
          f"{size:.2f} MB; switches: {' '.join(a.switches) or 'unchanged'}")
    return 0


def _interaction_bank(run, source, split, mirror=False):
    from inbetween_jax.errors import UserError
    from inbetween_jax.models.interaction.bank import MotionBank
    from inbetween_jax.models.interaction.config import Config
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    from inbetween_jax.train.config import config_from_dict
    cfg = config_from_dict(Config, run.config)
    pairs = split_pairs(load_pairs(source, cfg.data.pair_distance), split, cfg.data.split)
    J = int(run.extra["num_joints"])
    if pairs and pairs[0].feats.shape[2] != J:
        raise UserError(f"{source}: {pairs[0].feats.shape[2]} joints, the run has {J}")
    return MotionBank.from_pairs(pairs, cfg.data.pos_scale)


def _scvae_bank(run, source, split, mirror=False):
    import numpy as np

    from inbetween_jax.data import load_motions
    from inbetween_jax.data.datasets import window_settings
    from inbetween_jax.errors import UserError
    from inbetween_jax.models.scvae.bank import TransitionBank
    motions = load_motions(source, split)
    J = int(run.extra["num_joints"])
    if motions and motions[0].skeleton.num_joints != J:
        raise UserError(f"{source}: {motions[0].skeleton.num_joints} joints, the run has {J}")
    fa = window_settings(source, "train")["forward_axis"] or motions[0].skeleton.forward_axis()
    return TransitionBank.from_motions(motions, np.asarray(fa, np.float64), mirror=mirror)


BUILDERS = {"interaction": _interaction_bank, "scvae": _scvae_bank}     # model -> its bank, from the run's data


if __name__ == "__main__":
    sys.exit(main())
