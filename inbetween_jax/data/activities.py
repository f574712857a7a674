"""Activity groups of CMU trials, for per-activity tables (walk, run, jump, dance, martial arts, sports,
climb/playground, everyday).

Two sources: the ``group`` column of ``cmu_more/FILES.tsv`` in the shared mocap folder (the CMU index's
description of each trial, grouped), and for the trials outside it (``cmu_bvh/``, the embedded clips, the salsa
pairs) the table below, from the CMU index descriptions of those subjects' trials (subject 2: walk, run/jog,
jump; 3: walk on uneven terrain; 5-8, 10, 12: walk; 9: run; 13, 14: various everyday behaviours; 16_01 / 16_02:
jumps; 18: two-person everyday interaction; 60 / 61: salsa).  09_10 is labelled ``jump``: unlike the other
subject-9 runs its hips move 1.4 m vertically.  LaFAN1 files (``walk4_subject1.bvh``) are grouped by their
action (:data:`LAFAN1_ACTIONS`; falls, floor work and pushes are ``other``).  A name the tables do not know is
``other``.
"""
from __future__ import annotations

import csv
import functools
import os
import re

__all__ = ["GROUPS", "LAFAN1_ACTIONS", "activity_group", "trial_of"]

GROUPS = ("walk", "run", "jump", "dance", "martial arts/fight", "sports", "climb/playground", "everyday", "other")

_SUBJECT = {"02": "walk", "03": "walk", "05": "walk", "06": "walk", "07": "walk", "08": "walk", "09": "run",
            "10": "walk", "12": "walk", "13": "everyday", "14": "everyday", "18": "everyday", "60": "dance",
            "61": "dance"}
LAFAN1_ACTIONS = {"walk": "walk", "run": "run", "sprint": "run", "jumps": "jump", "dance": "dance",
                  "fight": "martial arts/fight", "fightAndSports": "sports", "obstacles": "climb/playground",
                  "aiming": "everyday"}
_TRIAL = {"02_03": "run", "02_04": "jump", "09_10": "jump", "16_01": "jump", "16_02": "jump"}


def trial_of(name: str) -> str | None:
    """``NN_MM`` of a file name or window name (``"07_05@120"``, ``"cmu_more/daz43/16_12.bvh"``), else None."""
    m = re.search(r"(?<!\d)(\d{2,3})_(\d{2})(?!\d)", os.path.basename(str(name)))
    return f"{m.group(1)}_{m.group(2)}" if m else None


@functools.lru_cache(maxsize=1)
def _files_tsv() -> dict:
    from inbetween_jax.paths import shared_data_dir
    root = shared_data_dir()
    path = os.path.join(root, "cmu_more", "FILES.tsv") if root else None
    if not path or not os.path.exists(path):
        return {}
    with open(path, newline="") as f:
        return {trial_of(r["file"]): r["group"] for r in csv.DictReader(f, delimiter="\t") if trial_of(r["file"])}


def activity_group(name: str) -> str:
    """The activity group (one of :data:`GROUPS`) of a CMU trial named in ``name``."""
    trial = trial_of(name)
    if trial is None:
        lafan1 = re.fullmatch(r"([A-Za-z]+)\d+_subject\d+(\.bvh)?", os.path.basename(str(name)))
        return LAFAN1_ACTIONS.get(lafan1.group(1), "other") if lafan1 else "other"
    if trial in _TRIAL:
        return _TRIAL[trial]
    tsv = _files_tsv().get(trial)
    if tsv:
        return tsv if tsv in GROUPS else "other"
    return _SUBJECT.get(trial.split("_")[0].zfill(2), "other")
