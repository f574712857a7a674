"""Checkpoint selection on a validation split cut from the training data (never the test windows).

A run trained with ``train.split="fit"`` (or ``"fit-subjects"``) holds the validation files out of training (see
:func:`inbetween_jax.data.datasets.split_files`).  :func:`select_checkpoint` scores every checkpoint of the
run with the model's ``bench.val_score(run, source)`` (lower is better) and writes ``selection.json`` beside
``run.json``; :func:`inbetween_jax.train.run.load_run` then opens the selected step unless a step is asked for
(the run-folder format, :mod:`inbetween_jax.train.run`, owns the file's name and reading it: this module only
chooses and writes).
"""
from __future__ import annotations

import json
import os
from typing import Callable

from inbetween_jax.train.run import SELECTION_FILE, RunError, _checkpoint_steps, load_run, selected_step

__all__ = ["SELECTION_FILE", "select_checkpoint", "select_with_bench", "selected_step", "time_to_score",
           "checkpoint_wall_times"]


def select_checkpoint(run_dir: str, source: str, score_fn: Callable, metric: str,
                      log: Callable[[str], None] | None = print, split: str = "val") -> dict:
    """Score each checkpoint of ``run_dir`` with ``score_fn(run) -> float`` (lower is better) on ``source``'s
    validation split ``split``; record and return ``{"metric", "split", "source", "scores": {step: score},
    "step"}``."""
    steps = _checkpoint_steps(os.path.join(run_dir, "checkpoints"))
    known = _known_scores(run_dir, source, metric, split)   # steps scored by an earlier selection: not again
    scores = {}
    for step in steps:
        if step == 0:
            continue
        if step in known:
            scores[step] = known[step]
            continue
        try:
            scores[step] = float(score_fn(load_run(run_dir, step)))
        except RunError as err:   # e.g. a checkpoint left unfinished by a killed run: not a candidate
            if log:
                log(f"validation: step {step}: skipped ({err})")
            continue
        if log:
            log(f"validation: step {step}: {metric} {scores[step]:.4f}")
    if not scores:
        return {}
    best = min(scores, key=lambda s: (scores[s], -s))
    out = {"metric": metric, "split": split, "source": source, "scores": {str(k): v for k, v in scores.items()},
           "step": int(best)}
    tmp = os.path.join(run_dir, SELECTION_FILE + ".tmp")
    with open(tmp, "w") as f:
        json.dump(out, f, indent=1)
    os.replace(tmp, os.path.join(run_dir, SELECTION_FILE))
    if log:
        log(f"selected step {best} ({metric} {scores[best]:.4f} on the validation split)")
    return out


def select_with_bench(run_dir: str, source: str, bench, log: Callable[[str], None] | None = print) -> dict:
    """:func:`select_checkpoint` with a model's ``bench.val_score`` on ``source``, recorded under the bench's
    ``VAL_METRIC`` name (default ``"val L2P"``; with the parameters' moving average in use, ``train.ema_decay``,
    the name says so)."""
    from inbetween_jax.data.datasets import val_split_of     # here: the datasets module imports JAX
    train = load_run(run_dir, need_checkpoint=False).config.get("train", {})
    split = val_split_of(train.get("split", "fit"))
    metric = getattr(bench, "VAL_METRIC", "val L2P")
    if train.get("ema_decay", 0.0) > 0 and train.get("ema_eval", True):
        metric += ", parameters' moving average"     # another score than the last parameters': not reused for them
    return select_checkpoint(run_dir, source, lambda r: bench.val_score(r, source), metric, log=log, split=split)


def time_to_score(run_dir: str, selection: dict, target: float) -> dict:
    """The first checkpoint of ``run_dir`` whose score in ``selection`` (:func:`select_checkpoint`'s record) is at
    most ``target``, and the training wall time up to it (``train_wall_s`` in the checkpoint's JSON, written by
    :func:`inbetween_jax.train.run_training`, resumed runs included): ``{"target", "step", "score",
    "train_wall_s"}`` (step None and no time when no checkpoint reaches the target; time None for a checkpoint
    written before the wall time was recorded)."""
    scores = {int(k): float(v) for k, v in selection.get("scores", {}).items()}
    hit = [s for s in sorted(scores) if scores[s] <= target]
    return {"target": float(target), "step": hit[0] if hit else None, "score": scores[hit[0]] if hit else None,
            "train_wall_s": checkpoint_wall_times(run_dir, hit[:1])[hit[0]] if hit else None}


def checkpoint_wall_times(run_dir: str, steps) -> dict:
    """{step: training wall seconds up to that checkpoint (``train_wall_s``; None where not recorded)}."""
    from inbetween_jax.train.checkpoint import Checkpointer
    out = {}
    with Checkpointer(os.path.join(run_dir, "checkpoints"), max_to_keep=None) as ck:
        for step in sorted(int(s) for s in steps):
            wall = ck.restore_extra(step).get("train_wall_s")
            out[step] = None if wall is None else float(wall)
    return out


def _known_scores(run_dir: str, source: str, metric: str, split: str = "val") -> dict:
    path = os.path.join(run_dir, SELECTION_FILE)
    try:
        with open(path) as f:
            old = json.load(f)
        if old.get("source") == source and old.get("metric") == metric and old.get("split", "val") == split:
            return {int(k): float(v) for k, v in old.get("scores", {}).items()}
    except (OSError, ValueError, TypeError, AttributeError):
        pass
    return {}
