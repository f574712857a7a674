"""Calibrate a run's out-of-distribution gate on its validation split (inbetween_jax/models/ood.py).

    python experiments/calibrate_gate.py RUN_DIR [--source cmu]

Writes RUN_DIR/ood.npz (bank + thresholds) and RUN_DIR/ood_calibration.json (per-window scores and ratios);
switch the gate on with model.ood_gate=true (ship_weights --set model.ood_gate=true).
"""
import argparse

from inbetween_jax.models.ood import calibrate_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("run_dir")
p.add_argument("--source", default="cmu")
a = p.parse_args()
print(calibrate_run(a.run_dir, a.source))
