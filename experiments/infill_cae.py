"""Fill gaps / de-noise / recover joints of a BVH file with a trained CAE checkpoint.

``python experiments/infill_cae.py --ckpt RUN_DIR --bvh IN.bvh --out OUT [--gap 100:160 ...]
[--noise SIGMA] [--dropout P] [--joints LeftForeArm,LeftHand] [--seed 0] [--keep-known]``

Writes ``OUT.npy`` (T, J, 3) global joint positions (cm; root trajectory from the integrated predicted
velocities, stitched to the input's trajectory at the gap ends), ``OUT.bvh`` and ``OUT.json`` (error vs the
input over the corrupted frames).  BVH rotations: outside the corrupted frames the input's rotations are
kept; on them the rotations start from the input's (slerped across each gap) and every bone is swung by
the shortest arc onto the predicted direction of its main child (twist is not estimated; bone lengths are
the skeleton's, so the BVH's FK differs slightly from the predicted positions -- ``fk_gap_cm``).
"""
from __future__ import annotations

import argparse
import json
import os
import sys


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ckpt", required=True, help="run folder written by experiments/train_cae.py")
    ap.add_argument("--bvh", required=True)
    ap.add_argument("--out", required=True, help="output path prefix")
    ap.add_argument("--gap", action="append", default=[], help="START:STOP frames to fill (repeatable)")
    ap.add_argument("--noise", type=float, default=0.0, help="Gaussian sigma on positions (normalised units)")
    ap.add_argument("--dropout", type=float, default=0.0, help="per-frame joint dropout probability")
    ap.add_argument("--joints", default="", help="comma-separated joint names missing over the whole clip")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep-known", action="store_true", help="paste the known input entries back")
    a = ap.parse_args(argv)

    import numpy as np

    from inbetween_jax.data import read_bvh, write_bvh
    from inbetween_jax.models.cae_infer import process_motion
    from inbetween_jax.models.cae_train import load_trained

    gaps = []
    for g in a.gap:
        s, e = g.split(":")
        gaps.append((int(s), int(e)))
    joints = [n for n in a.joints.split(",") if n]
    if not (gaps or a.noise or a.dropout or joints):
        ap.error("nothing to do: give --gap, --noise, --dropout or --joints")
    model = load_trained(a.ckpt)
    motion = read_bvh(a.bvh)
    res = process_motion(model, motion, gaps, a.noise, a.dropout, joints, a.seed, a.keep_known)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    np.save(a.out + ".npy", res["positions"])
    write_bvh(a.out + ".bvh", res["motion"])
    summary = {"input": a.bvh, "checkpoint": a.ckpt, "step": model.step, "frames": motion.num_frames,
               "gaps": gaps, "noise": a.noise, "dropout": a.dropout, "joints": joints,
               "error_cm_mean": res["error_cm"][0], "error_cm_std": res["error_cm"][1],
               "refit_frames": int(res["frames"].sum()), "fk_gap_cm": res["fk_gap_cm"]}
    with open(a.out + ".json", "w") as fh:
        json.dump(summary, fh, indent=1)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
