"""A CAE run's gaps inside files, as ``inbetween infill --model cae`` fills them (gate, motion matching and root
bound as the run's config and ``--set`` say): per activity group and length, the per-gap error over the run's
Hermite fill and over straight lines (:func:`inbetween_jax.models.cae.in_file.gap_records`, the bench's in-file
rows), on a split of the ``cmu`` source (default: the validation subjects).

    python experiments/cae_in_file.py RUN_DIR [--split val-subjects] [--set KEY=VALUE ...] [--json OUT]

``--set`` changes inference switches without retraining, e.g. ``--set model.ood_gate=false --set model.match_k=0``
for the network alone.  The bank a ``model.match_k`` needs is the run folder's ``bank.npz`` (``inbetween
build-bank``).
"""
import argparse
import dataclasses
import json
import time

from inbetween_jax.data import load_motions
from inbetween_jax.evaluation.worst_case import worst_case_markdown, worst_case_rows
from inbetween_jax.models.cae.config import get_config
from inbetween_jax.models.cae.in_file import gap_records
from inbetween_jax.models.cae.infer import load
from inbetween_jax.train.config import apply_overrides
from inbetween_jax.train.run import _added_keys, load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--split", default="val-subjects")
p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
p.add_argument("--json", default=None, help="write the rows here")
a = p.parse_args()
t0 = time.time()
run = load_run(a.run_dir)
full = _added_keys(run.config, dataclasses.asdict(get_config(run.preset)))     # switches newer than the run
run = dataclasses.replace(run, config=apply_overrides(full, a.set))
model = load(run)
motions = load_motions("cmu", a.split)
records = gap_records(model, motions)
rows = {key: worst_case_rows([dict(r, ratio=r[key]) for r in records], "per_window", "cmu", "cae", base, a.split)
        for key, base in (("ratio", "the Hermite fill"), ("x_straight", "straight lines"))}
matched = sum(r["matched"] for r in records)
for key, rs in rows.items():
    print(worst_case_markdown(rs, f"{a.run_dir} {' '.join(a.set)}: {a.split}, inside a file"))
    print()
print(f"{len(records)} gaps, {matched} matched, {time.time() - t0:.0f} s")
if a.json:
    with open(a.json, "w") as f:
        json.dump({"overrides": a.set, "split": a.split, "rows": rows}, f, indent=1)
