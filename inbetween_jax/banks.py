"""Write a run's motion bank and turn it on: an interaction run's (:mod:`inbetween_jax.models.interaction.bank`),
an S-CVAE run's (:mod:`inbetween_jax.models.scvae.bank`) or a CAE run's (the S-CVAE's format, matched in the CAE's
features by :mod:`inbetween_jax.models.cae.bank`).

    write_bank(run_dir, source=None, split="fit", mirror=False, switches=()) -> dict

builds the bank from the ``split`` motions (``fit``: the training files or takes without the validation ones,
so bank settings chosen on the validation split never saw it; the test files are never in it) of ``source``
(default: the run's own data source), writes ``RUN_DIR/bank.npz`` and applies the ``switches`` (``KEY=VALUE``
inference switches of the model's bank: its ``SWITCHES``) to ``RUN_DIR/run.json``.  ``mirror`` (S-CVAE banks):
the bank holds each motion's left-right mirror image too.  RUN_DIR is a training run or a shipped weights
folder.  Front end: ``inbetween build-bank``; the probes build the same banks in memory
(:func:`interaction_bank`, :func:`scvae_bank`).
"""
from __future__ import annotations

import importlib
import json
import os

import numpy as np

from inbetween_jax.errors import UserError
from inbetween_jax.train.run import RUN_FILE, RunError, load_run

__all__ = ["BUILDERS", "interaction_bank", "scvae_bank", "run_fit_split", "write_bank", "bank_folder"]


def interaction_bank(run, source: str, split: str = "fit", mirror: bool = False):
    """The :class:`~inbetween_jax.models.interaction.bank.MotionBank` of the ``split`` takes of ``source``."""
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


def scvae_bank(run, source: str, split: str = "fit", mirror: bool = False):
    """The :class:`~inbetween_jax.models.scvae.bank.TransitionBank` of the ``split`` motions of ``source`` (``run``:
    its joint count is checked; None skips the check)."""
    from inbetween_jax.data import load_motions
    from inbetween_jax.data.datasets import window_settings
    from inbetween_jax.models.scvae.bank import TransitionBank
    motions = load_motions(source, split)
    J = int(run.extra["num_joints"]) if run is not None else None
    if J is not None and motions and motions[0].skeleton.num_joints != J:
        raise UserError(f"{source}: {motions[0].skeleton.num_joints} joints, the run has {J}")
    fa = window_settings(source, "train")["forward_axis"] or motions[0].skeleton.forward_axis()
    return TransitionBank.from_motions(motions, np.asarray(fa, np.float64), mirror=mirror)


# model -> its bank, from the run's data (the CAE matches gaps in the S-CVAE's bank format: models/cae/bank.py)
BUILDERS = {"interaction": interaction_bank, "scvae": scvae_bank, "cae": scvae_bank}


def run_fit_split(run, split: str) -> str:
    """``split`` for a bank of ``run``: ``"fit"`` means the run's own fit split, so a run trained on
    ``train.split=fit-subjects`` gets a bank without its validation subjects (``fit`` alone holds out files by
    name, and would put those subjects' other files in the bank; ``fit-activities`` likewise)."""
    own = str(((run.config or {}).get("train") or {}).get("split", "train"))
    return own if split == "fit" and own in ("fit-subjects", "fit-activities") else split


def _shared_copy(model: str, run_dir: str, bank_path: str) -> str | None:
    """The folder beside ``run_dir`` (the shipped weights' layout: one folder per model) of another model whose bank
    has the same builder (:data:`BUILDERS`: the CAE matches in the S-CVAE's format) and the same bytes as
    ``bank_path``, or None."""
    import filecmp
    parent = os.path.dirname(os.path.normpath(run_dir))
    for other, builder in BUILDERS.items():
        sibling = os.path.join(parent, other, os.path.basename(bank_path))
        if (other != model and builder is BUILDERS[model] and os.path.isfile(sibling)
                and filecmp.cmp(sibling, bank_path, shallow=False)):
            return other
    return None


def bank_folder(run_dir: str, name: str) -> str:
    """The folder whose bank file ``name`` a run uses: its own, or, when it holds none and its ``run.json`` records
    ``bank.shared_with`` (:func:`write_bank` found the same bytes there), that sibling folder."""
    if not os.path.isfile(os.path.join(run_dir, name)):
        try:
            with open(os.path.join(run_dir, RUN_FILE)) as f:
                shared = (json.load(f).get("bank") or {}).get("shared_with")
        except (OSError, ValueError):
            shared = None
        if shared:
            return os.path.join(os.path.dirname(os.path.normpath(run_dir)), shared)
    return run_dir


def merged_switches(switches, new) -> list:
    """``KEY=VALUE`` items: ``switches`` with each key ``new`` sets replaced by its new item, in place, then the
    new keys after them."""
    new = {item.split("=", 1)[0]: item for item in new}
    out = [new.pop(item.split("=", 1)[0], item) for item in switches]
    return out + list(new.values())


def write_bank(run_dir: str, source: str | None = None, split: str = "fit", mirror: bool = False,
               switches=()) -> dict:
    """Build and write ``run_dir``'s bank, record it (and ``switches``) in its ``run.json``.

    Returns ``{"path", "bank", "bytes"}``.  Raises RunError / UserError (one line) for a folder of another model,
    an unknown switch, ``mirror`` on a non-S-CVAE run or data on another skeleton; nothing is written then."""
    from inbetween_jax.shipped import config_with_overrides
    run = load_run(run_dir, need_checkpoint=False)
    if run.model not in BUILDERS:
        raise RunError(f"{run_dir}: holds a {run.model} run; banks exist for {', '.join(BUILDERS)} runs")
    module = importlib.import_module(f"inbetween_jax.models.{run.model}.bank")
    bad = [s for s in switches if s.split("=", 1)[0] not in module.SWITCHES]
    if bad:
        raise RunError(f"--set {bad[0]}: not a bank switch (choose {', '.join(module.SWITCHES)})")
    if mirror and run.model != "scvae":
        raise RunError(f"--mirror: S-CVAE banks only ({run_dir} holds a {run.model} run)")
    source = source or run.data.get("source")
    split = run_fit_split(run, split)
    bank = BUILDERS[run.model](run, source, split, mirror)
    path = os.path.join(run_dir, RUN_FILE)
    with open(path) as f:
        meta = json.load(f)
    if switches:
        meta["config"] = config_with_overrides(run.model, meta["config"], list(switches))
        if "shipped" in meta:   # the export's record of its inference switches stays the config's
            meta["shipped"]["inference"] = merged_switches(meta["shipped"].get("inference", []), switches)
    meta["bank"] = {"source": source, "split": split, "mirror": mirror, "takes": list(bank.names),
                    "frames": bank.num_frames, "switches": list(switches) or meta.get("bank", {}).get("switches", [])}
    bank_path = os.path.join(run_dir, module.BANK_FILE)
    bank.save(bank_path)
    shared = _shared_copy(run.model, run_dir, bank_path)
    if shared:                  # the same bytes beside it: recorded, not stored twice
        os.remove(bank_path)
        meta["bank"]["shared_with"] = shared
        bank_path = os.path.join(os.path.dirname(os.path.normpath(run_dir)), shared, module.BANK_FILE)
    else:
        meta["bank"].pop("shared_with", None)
    with open(path + ".tmp", "w") as f:
        json.dump(meta, f, indent=1)
    os.replace(path + ".tmp", path)
    return {"path": bank_path, "bank": bank, "bytes": os.path.getsize(bank_path)}
