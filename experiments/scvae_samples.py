"""The S-CVAE's N samples on the validation subjects of a run's training split: APD, pairwise distance, mean-
and best-of-N error, the share that reach the keyframe, foot slide (inbetween_jax/models/scvae/samples.py).

    python experiments/scvae_samples.py RUN_DIR [RUN_DIR ...] [--source cmu] [--samples 10] [--set KEY=VALUE]
                                        [--split val-activities]

Prints one markdown table per run and writes RUN_DIR/samples_val.json (``--split S``: samples_S.json), or into
``--out DIR``; a folder of the package's shipped weights is never written to (its JSON goes to runs/samples/).
``--set`` changes inference switches (e.g. model.ood_gate=false, model.motion_spread=4) without retraining.
"""
import argparse
import dataclasses
import json
import os
import time

from inbetween_jax import shipped
from inbetween_jax.evaluation import markdown_table
from inbetween_jax.models.scvae.samples import COLUMNS, RATIO_COLUMNS, validation_rows
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dirs", nargs="+")
p.add_argument("--source", default="cmu")
p.add_argument("--samples", type=int, default=10)
p.add_argument("--split", default=None, help="held-out split (default: the validation split of the run's)")
p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
p.add_argument("--out", default=None, help="folder for the JSON (default: the run folder)")
a = p.parse_args()
package = os.path.realpath(os.path.join(os.path.dirname(shipped.__file__), "assets"))
for run_dir in a.run_dirs:
    t0 = time.time()
    run = load_run(run_dir)      # switches newer than the run take their defaults; --set checked, one-line errors
    run = dataclasses.replace(run, config=shipped.config_with_overrides(run.model, run.config, a.set))
    rows = validation_rows(run, a.source, num_samples=a.samples, split=a.split)
    cols = COLUMNS + RATIO_COLUMNS
    where = a.split or ("validation subjects" if a.source == "cmu" else "validation split")
    print(markdown_table(rows, cols, f"{run_dir} {' '.join(a.set)}: {where}, {a.samples} samples "
                                     f"({time.time() - t0:.0f} s)"))
    tag = "_".join(s.replace("model.", "").replace("=", "") for s in a.set)
    out = a.out or (os.path.join("runs", "samples") if os.path.realpath(run_dir).startswith(package + os.sep)
                     else run_dir)
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, f"samples_{a.split or 'val'}{'_' + tag if tag else ''}.json"), "w") as f:
        json.dump({"overrides": a.set, "rows": rows}, f, indent=1)
