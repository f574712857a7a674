"""LaFAN1 (Ubisoft La Forge, CC BY-NC-ND 4.0) from a folder of the shipped ``.bvh`` files.

Splits and windows follow the official benchmark (``lafan1/extract.py`` and ``benchmarks.py``):
subjects 1-4 train with 50-frame windows at offset 20; subject 5 test with 65-frame windows at offset 40;
10 past frames; windows centred in XZ on the mean root and turned so the hips face +X at frame 9.
"""
from __future__ import annotations

import os
import re

TRAIN_SUBJECTS = ("subject1", "subject2", "subject3", "subject4")
TEST_SUBJECTS = ("subject5",)
N_PAST = 10
TRAIN_WINDOW, TRAIN_OFFSET = 50, 20
BENCH_WINDOW, BENCH_OFFSET = 65, 40
NUM_JOINTS = 22
ROOT_FORWARD_AXIS = (0.0, 1.0, 0.0)  # LaFAN1 hips: local +Y points forward
CONTACT_VELFACTOR = 0.02  # official squared-displacement threshold (cm^2 per frame^2)
_NAME = re.compile(r"^(?P<seq>.+)_(?P<subject>subject\d+)\.bvh$")


def lafan1_files(directory, subjects) -> list:
    """Sorted paths of ``<action>_<subject>.bvh`` files in ``directory`` for ``subjects``.

    Raises FileNotFoundError naming the folder when it is missing or holds no matching file.
    """
    directory = os.fspath(directory)
    if not os.path.isdir(directory):
        raise FileNotFoundError(f"LaFAN1 folder {directory!r} does not exist (set LAFAN1_DIR to the folder "
                                "of extracted lafan1.zip .bvh files)")
    out = []
    for name in sorted(os.listdir(directory)):
        m = _NAME.match(name)
        if m and m.group("subject") in subjects:
            out.append(os.path.join(directory, name))
    if not out:
        raise FileNotFoundError(f"no LaFAN1 files for {', '.join(subjects)} in {directory!r} "
                                "(expected names like walk1_subject1.bvh)")
    return out


def split_spec(split: str) -> dict:
    """Subjects, window and offset of a named split: ``train``, ``test`` (50/20 on subject 5) or
    ``benchmark`` (65/40 on subject 5, the official evaluation windows)."""
    specs = {
        "train": dict(subjects=TRAIN_SUBJECTS, window=TRAIN_WINDOW, offset=TRAIN_OFFSET),
        "test": dict(subjects=TEST_SUBJECTS, window=TRAIN_WINDOW, offset=TRAIN_OFFSET),
        "benchmark": dict(subjects=TEST_SUBJECTS, window=BENCH_WINDOW, offset=BENCH_OFFSET),
    }
    if split not in specs:
        raise ValueError(f"unknown LaFAN1 split {split!r}; choose one of {sorted(specs)}")
    return specs[split]
