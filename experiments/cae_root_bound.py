"""Choose the CAE's ``model.root_bound`` on the validation subjects: global joint error of ``inbetween infill``'s
fill (root path bounded to within B metres of the limited Hermite root path) over linear interpolation of the
global joint positions, per gap.

    python experiments/cae_root_bound.py RUN_DIR [--bounds 0,0.05,0.1,0.2,0.4] [--split val-subjects] [--gate]
"""
import argparse
import dataclasses

import numpy as np

from inbetween_jax.data import load_motions
from inbetween_jax.evaluation.worst_case import summarise
from inbetween_jax.geometry import forward_kinematics
from inbetween_jax.models.cae.in_file import gap_starts
from inbetween_jax.models.cae.infer import load, process_motion
from inbetween_jax.models.ood import load_gate
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--bounds", default="0,0.05,0.1,0.2,0.4")
p.add_argument("--split", default="val-subjects")
p.add_argument("--seconds", default="1,2")
p.add_argument("--gate", action="store_true", help="with the run's calibrated out-of-distribution gate")
a = p.parse_args()
model = load(load_run(a.run_dir))
if a.gate:
    model.gate = load_gate(a.run_dir)
    model.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, ood_gate=True))
motions = load_motions("cmu", a.split)
for bound in [float(b) for b in a.bounds.split(",")]:
    model.cfg = dataclasses.replace(model.cfg, model=dataclasses.replace(model.cfg.model, root_bound=bound))
    ratios, root = [], []
    for m in motions:
        gp = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)[1]
        for sec in [float(s) for s in a.seconds.split(",")]:
            g = int(round(sec * m.fps))
            for lo in gap_starts(m.num_frames, g):
                pos = process_motion(model, m, [(lo, lo + g)])["positions"]
                w = (np.arange(1, g + 1) / (g + 1))[:, None, None]
                lin = gp[lo - 1] + w * (gp[lo + g] - gp[lo - 1])
                err = np.linalg.norm(pos[lo:lo + g] - gp[lo:lo + g], axis=-1).mean()
                ratios.append(err / np.linalg.norm(lin - gp[lo:lo + g], axis=-1).mean())
                root.append(np.linalg.norm((pos[lo:lo + g, 0] - gp[lo:lo + g, 0])[:, [0, 2]], axis=-1).max())
    s = summarise(ratios)
    print(f"bound {bound:g} m: {s['windows']} gaps, global error / linear's mean {s['mean']:.3f} median "
          f"{s['median']:.3f} p90 {s['p90']:.3f} max {s['max']:.3f}; worst root distance {max(root):.1f} cm")
