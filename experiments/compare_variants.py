"""Variants of one model compared on the validation subjects, from what training and calibration wrote:

    python experiments/compare_variants.py RUN_DIR [RUN_DIR ...]

For each run folder (trained with ``train.split=fit-subjects``, then ``inbetween calibrate-gate``): the
checkpoint-selection score (``selection.json``) and, per activity group and length, the per-window error ratio
to the model's base for the network alone and behind its calibrated gate (``ood_calibration.json``): mean,
90th percentile and maximum.  Test windows are never read.
"""
import argparse
import json
import os

from inbetween_jax.evaluation.worst_case import worst_case_rows
from inbetween_jax.models.ood import load_gate
from inbetween_jax.models.ood_runs import gated_records


def rows_of(run_dir: str) -> list:
    with open(os.path.join(run_dir, "selection.json")) as f:
        sel = json.load(f)
    with open(os.path.join(run_dir, "ood_calibration.json")) as f:
        cal = json.load(f)
    alone = [{"name": r["name"], "frames": r["frames"], "ratio": r["ratios_at"][-1]} for r in cal["records"]]
    gated = gated_records(cal, load_gate(run_dir)[1])
    out = []
    for what, recs in (("network alone", alone), ("gated", gated)):
        for r in worst_case_rows(recs, "variants", cal.get("source", "cmu"), cal["model"], "base", "validation"):
            out.append({"run": os.path.basename(os.path.normpath(run_dir)), "selection": sel["scores"][str(sel["step"])],
                        "step": sel["step"], "what": what, **{k: r[k] for k in ("group", "frames", "windows", "mean",
                                                                                 "p90", "max")}})
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_dirs", nargs="+")
    a = p.parse_args()
    print("| run | selection (val) | step | fill | group | frames | windows | mean | p90 | max |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for d in a.run_dirs:
        for r in rows_of(d):
            print(f"| {r['run']} | {r['selection']:.4f} | {r['step']} | {r['what']} | {r['group']} | {r['frames']} | "
                  f"{r['windows']} | {r['mean']:.3f} | {r['p90']:.3f} | {r['max']:.3f} |")


if __name__ == "__main__":
    main()
