"""Result tables: one markdown formatter and one flat record format for every benchmark.

    markdown_table(rows, ("L2P", "L2Q"), "title", keys=("frames", "method"))  -> str
    flat_rows(rows, table="official", data="lafan1", model="slerp", keys=("frames",)) -> [record, ...]

A *row* is a dict holding key columns (``frames``, ``method``, ``gap_s`` ...) and metric columns.  A *record*
(``results/bench.json`` ``rows``) is one number: ``{"table", "data", "model", "variant", <key columns>,
"metric", "value"}``, so scripts and plots read results without parsing markdown.
"""
from __future__ import annotations

import math
from typing import Iterable, Sequence

__all__ = ["format_value", "markdown_table", "flat_rows"]


def format_value(v, digits: int = 4) -> str:
    """``None`` / NaN -> ``-``; ``|v| < 10`` -> ``digits`` decimals; else 2 decimals; strings as they are."""
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    v = float(v)
    if math.isnan(v):
        return "-"
    return f"{v:.{digits}f}" if abs(v) < 10 else f"{v:.2f}"


def markdown_table(rows: Sequence[dict], columns: Iterable[str], title: str = "",
                   keys: Sequence[str] = ("frames", "method"), digits: int = 4) -> str:
    """Rows of dicts -> a GitHub markdown table: the ``keys`` columns first, then ``columns``."""
    columns = list(columns)
    head = list(keys) + columns
    out = ([f"**{title}**", ""] if title else []) + ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [str(r.get(k, "")) for k in keys] + [format_value(r.get(c), digits) for c in columns]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def flat_rows(rows: Sequence[dict], table: str, data: str, model: str | None = None, variant: str = "",
              keys: Sequence[str] = ("frames",), method_key: str = "method") -> list[dict]:
    """One record per numeric cell of ``rows`` (see the module docstring).

    ``model`` defaults to each row's ``method_key`` value; ``keys`` are copied into every record.
    """
    out = []
    for r in rows:
        base = {"table": table, "data": data, "model": model if model is not None else str(r.get(method_key, "")),
                "variant": variant if variant or model is None else str(r.get(method_key, ""))}
        base.update({k: r[k] for k in keys if k in r})
        for name, value in r.items():
            if name in keys or name == method_key or isinstance(value, (str, bool)) or value is None:
                continue
            if isinstance(value, (int, float)):
                out.append({**base, "metric": name, "value": float(value)})
    return out
