"""A run folder's gate calibration: ``inbetween calibrate-gate RUN_DIR`` (:func:`calibrate_run`, ``--keep-gate``:
:func:`calibrate_additions_run`) writes ``ood.npz`` (:func:`inbetween_jax.models.ood.save_gate`) and
``ood_calibration.json``, the validation windows' scores and error ratios behind the gate, which the tables and
figures read back (:func:`gated_records`, :func:`calibration_worst_case`).  Each model's own choice lives in
``models/<model>/calibrate.py``; nothing here looks at test windows.
"""
from __future__ import annotations

import os

import numpy as np

from inbetween_jax.models.ood import OOD_FILE, gated_ratio, optional_gate_arrays, save_gate

__all__ = ["CALIBRATION_FILE", "calibrate_run", "calibrate_additions_run", "gated_records", "calibration_worst_case"]

CALIBRATION_FILE = "ood_calibration.json"        # per-window scores and ratios behind the gate (figures, tables)


def calibrate_run(run_dir: str, source: str, **kwargs) -> dict:
    """Calibrate the gate of the run in ``run_dir`` on its validation split (``models/<model>/calibrate.py``'s
    ``calibrate``) and write ``ood.npz`` and ``ood_calibration.json`` (summary + per-window records) into it.
    Returns the calibration's summary."""
    import importlib
    import json
    from inbetween_jax.train.run import load_run
    run = load_run(run_dir)
    res = importlib.import_module(f"inbetween_jax.models.{run.model}.calibrate").calibrate(run, source, **kwargs)
    save_gate(run_dir, res["bank"], res["gate"], res["summary"], res.get("arrays"))
    tmp = os.path.join(run_dir, CALIBRATION_FILE + ".tmp")
    with open(tmp, "w") as f:
        json.dump({"model": run.model, "step": int(run.step), "source": source, "summary": res["summary"],
                   "records": res["records"], **_extra_records(res)}, f)
    os.replace(tmp, os.path.join(run_dir, CALIBRATION_FILE))
    return res["summary"]


def _extra_records(res: dict) -> dict:
    """A calibration's records beside the gate's own (``context_records``: the S-CVAE's gaps inside clips)."""
    return {k: v for k, v in res.items() if k.endswith("_records")}


def calibrate_additions_run(run_dir: str, source: str) -> dict:
    """Add (or redo) what a model's calibration adds to its gate (``models/<model>/calibrate.py``'s
    ``calibrate_additions``: the S-CVAE's thresholds inside a clip, the CAE's k-NN cap) in ``run_dir``'s
    ``ood.npz`` and ``ood_calibration.json``, keeping the gate itself as it is (``inbetween calibrate-gate RUN_DIR
    --keep-gate``).  Returns the new summary numbers.

    Raises:
        RunError: the folder holds no calibrated gate (one line).
    """
    import importlib
    import json
    from inbetween_jax.train.run import RunError, load_run
    run = load_run(run_dir)
    path, cal_path = os.path.join(run_dir, OOD_FILE), os.path.join(run_dir, CALIBRATION_FILE)
    if not (os.path.exists(path) and os.path.exists(cal_path)):
        raise RunError(f"{run_dir}: no calibrated gate to add to (run `inbetween calibrate-gate {run_dir}` first)")
    arrays = optional_gate_arrays(run_dir, "")          # every array; unreadable: one line, before the calibration
    res = importlib.import_module(f"inbetween_jax.models.{run.model}.calibrate").calibrate_additions(run, source)
    arrays.update({k: np.asarray(v) for k, v in res["arrays"].items()})
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, **arrays)
    with open(cal_path) as f:
        cal = json.load(f)
    cal["summary"].update(res["summary"])
    cal.update(_extra_records(res))
    with open(cal_path + ".tmp", "w") as f:
        json.dump(cal, f)
    os.replace(tmp, path)
    os.replace(cal_path + ".tmp", cal_path)
    return res["summary"]


def gated_records(calibration: dict, gate) -> list:
    """Records of a gate's calibration file (``ood_calibration.json``: the validation windows) at the weights
    ``gate`` gives them (:func:`inbetween_jax.models.ood.gated_ratio`)."""
    recs = calibration["records"]
    w = gate.weight([r["score"] for r in recs]) * np.array([r.get("cap_weight", 1.0) for r in recs])
    ratio = gated_ratio([r["ratios_at"] for r in recs], w)
    return [{"name": r["name"], "frames": r["frames"], "ratio": float(x), "score": r["score"], "weight": float(wi)}
            for r, x, wi in zip(recs, ratio, w)]


def calibration_worst_case(run_dir: str, gate, model: str, base: str, split: str = "validation subjects") -> list:
    """Worst-case rows (:func:`inbetween_jax.evaluation.worst_case.worst_case_rows`, split ``split``) of the gate's
    calibration windows in ``run_dir/ood_calibration.json``, scored at the weights the gate ((scorer, Gate)) gives
    them; [] without a gate or that file."""
    import json
    from inbetween_jax.evaluation.worst_case import worst_case_rows
    path = os.path.join(run_dir, CALIBRATION_FILE)
    if gate is None or not os.path.exists(path):
        return []
    with open(path) as f:
        cal = json.load(f)
    return worst_case_rows(gated_records(cal, gate[1]), "per_window", cal.get("source", "cmu"), model, base, split)
