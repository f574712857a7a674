"""Write a run's motion bank and turn it on (:func:`inbetween_jax.banks.write_bank`).

    python experiments/build_bank.py RUN_DIR [--source DIR] [--split fit] [--mirror] [--set model.bank_k=8 ...]

``--split fit`` (default): the training files or takes without the validation ones; ``--set``: the model's bank
switches (interaction: ``model.bank_k``, ``model.bank_weight``, ``model.texture_sigma``, ``model.texture_gain``;
S-CVAE: ``model.bank_k``, ``model.bank_weight``, ``model.bank_tau``), written into ``RUN_DIR/run.json``;
``--mirror`` (S-CVAE): each motion's mirror image too.  RUN_DIR is a training run or a shipped weights folder.
"""
from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir", metavar="RUN_DIR")
    ap.add_argument("--source", default=None, help="data source (default: the run's data source)")
    ap.add_argument("--split", default="fit", choices=("fit", "train"), help="motions the bank holds")
    ap.add_argument("--mirror", action="store_true", help="S-CVAE: add each motion's mirror image to the bank")
    ap.add_argument("--set", dest="switches", action="append", default=[], metavar="KEY=VALUE",
                    help="bank switch written into run.json, e.g. model.bank_k=8 (repeatable)")
    a = ap.parse_args(argv)
    from inbetween_jax.banks import write_bank
    from inbetween_jax.errors import UserError
    try:
        out = write_bank(a.run_dir, a.source, a.split, a.mirror, a.switches)
    except (UserError, ValueError, OSError) as e:          # RunError is a ValueError
        print(f"build_bank: error: {e}", file=sys.stderr)
        return 2
    bank = out["bank"]
    names = ", ".join(bank.names) if len(bank.names) <= 12 else f"{', '.join(bank.names[:3])}, ..."
    print(f"{out['path']}: {len(bank.names)} clips ({names}), {bank.num_frames} frames, "
          f"{out['bytes'] / 2 ** 20:.2f} MB; switches: {' '.join(a.switches) or 'unchanged'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
