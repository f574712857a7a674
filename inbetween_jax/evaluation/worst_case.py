"""The worst case, not just the mean: per-window error ratios to a model's base, summarised per length and per
activity group (:mod:`inbetween_jax.data.activities`).

A record is one scored window (or clip and gap): ``{"name": source or window name, "frames": length,
"ratio": model error / base error}``.  :func:`summarise` gives median, 90th percentile, maximum, mean and the
share of windows more than 10 % worse than the base; :func:`worst_case_rows` one flat row per (group, length)
plus ``"all"``, with the per-window ratios kept (``per_window``) for the distribution figure.
"""
from __future__ import annotations

import numpy as np

__all__ = ["WORSE", "summarise", "worst_case_rows", "worst_case_markdown"]

WORSE = 1.10            # "more than 10 % worse than its base"


def summarise(ratios) -> dict:
    """``{"windows", "mean", "median", "p90", "max", "share_worse_10pct"}`` of per-window ratios (n,)."""
    r = np.asarray(ratios, np.float64)
    if r.size == 0:
        return {"windows": 0}
    return {"windows": int(r.size), "mean": float(r.mean()), "median": float(np.median(r)),
            "p90": float(np.quantile(r, 0.9)), "max": float(r.max()), "share_worse_10pct": float(np.mean(r > WORSE))}


def worst_case_rows(records, table: str, data: str, model: str, base: str, split: str) -> list:
    """Flat rows (``table``, ``data``, ``model``, ``base``, ``split``, ``group``, ``frames``, the
    :func:`summarise` numbers, ``per_window``) per activity group and length, and ``group="all"``."""
    from inbetween_jax.data.activities import activity_group
    out = []
    groups = {}
    for r in records:
        for g in (activity_group(r["name"]), "all"):
            groups.setdefault((g, int(r["frames"])), []).append(float(r["ratio"]))
    for (g, n), ratios in sorted(groups.items(), key=lambda kv: (kv[0][0] != "all", kv[0][0], kv[0][1])):
        out.append({"table": table, "data": data, "model": model, "base": base, "split": split, "group": g,
                    "frames": n, **summarise(ratios), "per_window": [round(x, 4) for x in ratios]})
    return out


def worst_case_markdown(rows, title: str) -> str:
    """A markdown table of :func:`worst_case_rows` (groups as rows, lengths as column blocks)."""
    if not rows:
        return ""
    lines = [f"**{title}** (per-window error / {rows[0]['base']}'s; share: windows more than 10 % worse)", "",
             "| group | frames | windows | mean | median | p90 | max | share > 1.10x |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['group']} | {r['frames']} | {r['windows']} | {r['mean']:.3f} | {r['median']:.3f} | "
                     f"{r['p90']:.3f} | {r['max']:.3f} | {100 * r['share_worse_10pct']:.0f} % |")
    return "\n".join(lines)

