"""Metric logging: ``metrics.csv`` + ``metrics.jsonl`` (+ optional TensorBoard) and a tqdm bar.

Files are opened in append mode so a resumed run continues the same files.  On construction with
``resume_step=N`` every existing row whose ``step`` is greater than ``N`` is dropped (those steps are
about to be recomputed), so the curve never holds duplicate steps.  TensorBoard events are written
only when ``tensorboardX`` (or ``torch.utils.tensorboard`` with ``tensorboard``) is importable;
otherwise that output is silently skipped.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import os
from typing import Any, Mapping

import numpy as np
from tqdm.auto import tqdm

__all__ = ["MetricLogger", "ProgressBar", "format_metrics"]


def _scalar(name: str, value: Any) -> float | int:
    arr = np.asarray(value)
    if arr.shape != ():
        raise ValueError(f"metric '{name}' must be a scalar, got shape {arr.shape}")
    return arr.item()


def _tb_writer(log_dir: str) -> Any:
    """A SummaryWriter if a TensorBoard writer library is importable, else None."""
    try:
        from tensorboardX import SummaryWriter  # type: ignore
        return SummaryWriter(log_dir)
    except ImportError:
        pass
    if importlib.util.find_spec("tensorboard") is not None and importlib.util.find_spec("torch") is not None:
        try:
            from torch.utils.tensorboard import SummaryWriter  # type: ignore
            return SummaryWriter(log_dir)
        except ImportError:
            pass
    return None


class MetricLogger:
    """Append-only scalar logger for one run directory.

    Args:
        run_dir: folder receiving ``metrics.csv``, ``metrics.jsonl`` and (optionally) ``tb/``.
        resume_step: if given, rows with ``step > resume_step`` already in the files are removed
            (``0`` = fresh start: clears everything).  ``None`` keeps all existing rows.
        tensorboard: try to also write TensorBoard events.

    Each row is ``{"step": int, <name>: float, ...}``; metric values must be scalars (python, numpy or jax).
    """

    def __init__(self, run_dir: str | os.PathLike, resume_step: int | None = None, tensorboard: bool = True):
        self.run_dir = os.path.abspath(os.fspath(run_dir))
        os.makedirs(self.run_dir, exist_ok=True)
        self.csv_path = os.path.join(self.run_dir, "metrics.csv")
        self.jsonl_path = os.path.join(self.run_dir, "metrics.jsonl")
        rows = self._read_jsonl()
        if resume_step is not None:
            rows = [r for r in rows if int(r.get("step", 0)) <= resume_step]
        self._fields: list[str] = ["step"]
        for r in rows:
            self._add_fields(r)
        self._rewrite(rows)
        self._jsonl = open(self.jsonl_path, "a", encoding="utf-8")
        self._csv = open(self.csv_path, "a", encoding="utf-8", newline="")
        self._tb = _tb_writer(os.path.join(self.run_dir, "tb")) if tensorboard else None

    def _read_jsonl(self) -> list[dict]:
        if not os.path.exists(self.jsonl_path):
            return []
        rows = []
        with open(self.jsonl_path, encoding="utf-8") as f:
            for line in f:
                try:
                    rows.append(json.loads(line))
                except json.JSONDecodeError:  # a line torn by a kill mid-write
                    continue
        return rows

    def _add_fields(self, row: Mapping[str, Any]) -> bool:
        new = [k for k in row if k not in self._fields]
        self._fields.extend(new)
        return bool(new)

    def _rewrite(self, rows: list[dict], jsonl: bool = True) -> None:
        """Atomically rewrite the CSV (and the JSONL file, the source of truth, if ``jsonl``) from ``rows``."""
        outputs = [(self.csv_path, "csv")] + ([(self.jsonl_path, "jsonl")] if jsonl else [])
        for path, fmt in outputs:
            tmp = path + ".tmp"
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                if fmt == "jsonl":
                    f.writelines(json.dumps(r) + "\n" for r in rows)
                else:
                    w = csv.DictWriter(f, fieldnames=self._fields, restval="")
                    w.writeheader()
                    w.writerows(rows)
            os.replace(tmp, path)

    def log(self, step: int, metrics: Mapping[str, Any]) -> dict:
        """Append one row; returns it as ``{"step": step, name: python scalar}``."""
        row = {"step": int(step)}
        row.update({k: _scalar(k, v) for k, v in metrics.items() if k != "step"})
        self._jsonl.write(json.dumps(row) + "\n")
        self._jsonl.flush()
        if self._add_fields(row):  # new column: rewrite the CSV with the widened header
            self._csv.close()
            self._rewrite(self._read_jsonl(), jsonl=False)  # the open JSONL handle must keep its file
            self._csv = open(self.csv_path, "a", encoding="utf-8", newline="")
        else:
            csv.DictWriter(self._csv, fieldnames=self._fields, restval="").writerow(row)
            self._csv.flush()
        if self._tb is not None:
            for k, v in row.items():
                if k != "step" and isinstance(v, (int, float)) and math.isfinite(v):
                    self._tb.add_scalar(k, v, row["step"])
        return row

    def close(self) -> None:
        """Flush and close all files."""
        for f in (self._jsonl, self._csv):
            if not f.closed:
                f.close()
        if self._tb is not None:
            self._tb.close()
            self._tb = None

    def __enter__(self) -> "MetricLogger":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def format_metrics(metrics: Mapping[str, Any], digits: int = 4) -> dict[str, str]:
    """``{"loss": 0.12345678}`` -> ``{"loss": "0.1235"}`` (for tqdm postfix)."""
    out = {}
    for k, v in metrics.items():
        if k == "step":
            continue
        v = np.asarray(v).item() if np.ndim(v) == 0 else v
        out[k] = f"{v:.{digits}g}" if isinstance(v, float) else str(v)
    return out


class ProgressBar:
    """tqdm bar over training steps whose postfix shows the latest losses.

    Args:
        total: last step number; initial: step the run starts (resumes) from; disable: no output.
    """

    def __init__(self, total: int, initial: int = 0, desc: str = "train", disable: bool = False):
        self._bar = tqdm(total=total, initial=initial, desc=desc, disable=disable, dynamic_ncols=True)

    def update(self, n: int = 1, metrics: Mapping[str, Any] | None = None) -> None:
        """Advance by ``n`` steps and, if given, show ``metrics`` as the postfix."""
        if metrics is not None:
            self._bar.set_postfix(format_metrics(metrics), refresh=False)
        self._bar.update(n)

    def close(self) -> None:
        self._bar.close()
