"""A CAE run's gaps inside files, as ``inbetween infill --model cae`` fills them (gate, motion matching and root
bound as the run's config and ``--set`` say): per activity group and length, the per-gap error over the run's
Hermite fill and over straight lines (:func:`inbetween_jax.models.cae.in_file.gap_records`, the bench's in-file
rows), on a split of the ``cmu`` source (default: the validation subjects) or on BVH files of any rig and rate, matched
to the run's joints and resampled as ``infill`` does (``--files``: e.g. the salsa dancers of ``cmu_pairs``, motion
no CAE was trained on).  Also printed: how much the joints' steps change across the keyframes (the fill's against
the capture's; a fill that stops a moving joint at the keyframe, or leaves it too fast, shows a larger change), by
what filled the gap.

    python experiments/cae_in_file.py RUN_DIR [--split val-subjects | --files F.bvh ...] [--set KEY=VALUE ...]
                                      [--json OUT]

``--set`` changes inference switches without retraining, e.g. ``--set model.ood_gate=false --set model.match_k=0``
for the network alone.  The bank a ``model.match_k`` needs is the run folder's ``bank.npz`` (``inbetween
build-bank``).
"""
import argparse
import dataclasses
import json
import time

import numpy as np

from inbetween_jax.data import load_motions, read_bvh
from inbetween_jax.data.retarget import prepare
from inbetween_jax.evaluation.worst_case import worst_case_markdown
from inbetween_jax.models.cae.in_file import BASES, base_rows, gap_records
from inbetween_jax.models.cae.infer import load
from inbetween_jax.shipped import config_with_overrides
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--split", default="val-subjects")
p.add_argument("--files", nargs="+", default=None, help="BVH files instead of a split")
p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
p.add_argument("--json", default=None, help="write the rows here")
a = p.parse_args()
t0 = time.time()
run = load_run(a.run_dir)
run = dataclasses.replace(run, config=config_with_overrides(run.model, run.config, a.set))
model = load(run)
if a.files:
    motions = [prepare(read_bvh(f), f, model.skeleton, run.fps).motion for f in a.files]
    data, split = "files", f"{len(a.files)} files"
else:
    motions, data, split = load_motions("cmu", a.split), "cmu", a.split
records = gap_records(model, motions)
rows = base_rows(records, data, f"{split}, inside a file")
matched = sum(r["matched"] for r in records)
for _, base in BASES:
    print(worst_case_markdown([r for r in rows if r["base"] == base], f"{a.run_dir} {' '.join(a.set)}: {split}, "
                                                                       "inside a file"))
    print()
print("How much the joints' steps change across the keyframes, cm per frame: the fill's (the capture's), by what "
      "filled the gap")
for kind, keep in (("matched training motion", lambda r: r["matched"]),
                   ("the network (gate weight > 0.5)", lambda r: not r["matched"] and r.get("gate_weight", 0) > 0.5),
                   ("the base", lambda r: not r["matched"] and r.get("gate_weight", 0) <= 0.5)):
    sel = [r for r in records if keep(r)]
    if sel:
        print(f"- {kind}: {np.mean([r['step_change'] for r in sel]):.3f} "
              f"({np.mean([r['step_change_capture'] for r in sel]):.3f}), {len(sel)} gaps")
print(f"{len(records)} gaps, {matched} matched, {time.time() - t0:.0f} s")
if a.json:
    with open(a.json, "w") as f:
        json.dump({"overrides": a.set, "split": split, "rows": rows, "records": records}, f, indent=1)
