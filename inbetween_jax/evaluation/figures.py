"""Figures of the bench's results (matplotlib, Agg), drawn from its flat records (``bench.json`` ``rows``).

    bench_figures(rows, results_dir)          -> [{"path", "data", "series": {panel: [labels]}}, ...]
    figures_markdown(rows, results_dir)       -> markdown linking the PNGs (what ``inbetween bench`` appends)
    ratio_distribution(rows, path)            -> {"path", "series": {frames: [labels]}} or None

A record is one number (``evaluation.tables.flat_rows``): ``{"table", "data", "model", "variant", "frames",
"metric", "value"}`` (+ ``"weights": "shipped"`` for the shipped weights' rows).  :func:`bench_figures` draws one
PNG per data set, ``bench_<data>.png``: error against transition length, one panel per table it knows
(:data:`PANELS`), one line per model / variant, baselines dashed.  A model with no finite number in a panel is
left out of it; a data set with no panel to draw gets no figure.  The bench's sections name one source in
different ways (``cmu-embedded`` / ``embedded``, ``bvh-folder`` / ``bvh`` / ``cmu``); :data:`DATA_ALIASES` puts them
in one figure.

:func:`ratio_distribution` draws the per-window ratio to each model's base (Slerp, linear fill, interpolation) as
box plots, one panel per transition length, from records holding a ``per_window`` list of ratios.

Every writer draws into a temporary file beside the target and renames it into place
(``viz_frames.save_atomic``), so a failed drawing leaves no half-written PNG.
"""
from __future__ import annotations

import math
import os
import re
from typing import Iterable, Sequence

import matplotlib

matplotlib.use("Agg")  # no screen: never pick an interactive backend from the environment
import matplotlib.pyplot as plt  # noqa: E402

from inbetween_jax.viz_frames import save_atomic  # noqa: E402

__all__ = ["PANELS", "BASELINE_MODELS", "DATA_ALIASES", "canonical_data", "series_label", "bench_figures",
           "figures_markdown", "ratio_distribution"]

# (table, metric, panel title, y label): the tables drawn as error against transition length, in this order
PANELS = (
    ("table1", "L2P", "S-CVAE Table 1 layout (1 past keyframe)", "L2P"),
    ("official", "L2P", "Official LaFAN1 protocol (10 past frames)", "L2P"),
    ("cae_table1", "mpjpe_cm", "CAE: gap filling", "joint error over the gap (cm)"),
    ("interaction_table1", "L2P", "Interaction: two characters", "L2P"),
)
# non-learned rows, drawn dashed (model names as the benches write them)
BASELINE_MODELS = frozenset({"Slerp", "Zero-velocity", "slerp", "slerp_velocity", "linear", "hermite",
                             "hermite_context", "interpolation", "interpolation_guess", "hold", "bank"})
SKIPPED_MODELS = frozenset({"ground_truth", "paper"})   # zero error / another data set's published numbers
DATA_ALIASES = {"cmu-embedded": "embedded", "bvh-folder": "bvh", "cmu": "bvh"}


def canonical_data(name) -> str:
    """One name per data set (the sections of one bench label it differently)."""
    name = str(name or "unknown")
    return DATA_ALIASES.get(name, name)


def series_label(record: dict) -> str:
    """``model (variant)``, the variant alone when it names the model already; ``[shipped]`` for shipped weights
    (not on the baseline rows of a shipped model's section)."""
    model, variant = str(record.get("model", "")), str(record.get("variant", "") or "")
    label = variant if variant and (model in ("interaction", "bank") or model.lower() in variant.lower()) \
        else f"{model} ({variant})" if variant and variant != model else model
    shipped = record.get("weights") == "shipped" and model not in BASELINE_MODELS   # its section's Slerp is Slerp
    return label + (" [shipped]" if shipped else "")


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _panel_series(rows: Iterable[dict], table: str, metric: str) -> dict:
    """{label: {frames: value}} of one panel: finite values at frames > 0; duplicate labels (any case) once."""
    series: dict = {}
    seen: dict = {}
    for r in rows:
        if r.get("table") != table or r.get("metric") != metric or r.get("model") in SKIPPED_MODELS:
            continue
        frames, value = r.get("frames"), r.get("value")
        if not _finite(frames) or frames <= 0 or not _finite(value):
            continue
        label = series_label(r)
        key = seen.setdefault(label.lower(), label)   # Slerp from the baseline table and from a model's section
        series.setdefault(key, {}).setdefault(int(frames), float(value))
    return series


def _style(label: str, models: dict) -> dict:
    return {"ls": "--", "lw": 1.3} if models.get(label) in BASELINE_MODELS else {"ls": "-", "lw": 2.0}


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "data"


def _save(fig, path, dpi: int, **savefig) -> None:
    """Lay out ``fig`` and write it as a PNG atomically (``save_atomic``: nothing half-written)."""
    fig.tight_layout()
    save_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=dpi, facecolor="white", **savefig), ".png")


def _draw(panels: list, path: str, title: str, dpi: int) -> None:
    fig = plt.figure(figsize=(8.0, 3.0 * len(panels)), dpi=dpi, facecolor="white")
    try:
        for i, (ptitle, ylabel, series, models) in enumerate(panels):
            ax = fig.add_subplot(len(panels), 1, i + 1)
            for label, points in series.items():
                xs = sorted(points)
                ax.plot(xs, [points[x] for x in xs], marker="o", ms=3.5, label=label, **_style(label, models))
            ax.set_title(ptitle, fontsize=10)
            ax.set_xlabel("transition length (frames)")
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.suptitle(title, fontsize=11)
        _save(fig, path, dpi, bbox_inches="tight")
    finally:
        plt.close(fig)


def bench_figures(rows: Sequence[dict], results_dir, dpi: int = 100) -> list:
    """One PNG per data set of ``rows``: error against transition length (see the module docstring).

    Returns ``[{"path", "data", "series": {panel title: [labels drawn]}}]``, one entry per PNG written.
    """
    by_data: dict = {}
    for r in rows:
        by_data.setdefault(canonical_data(r.get("data")), []).append(r)
    out = []
    for data in sorted(by_data):
        panels = []
        for table, metric, ptitle, ylabel in PANELS:
            series = _panel_series(by_data[data], table, metric)
            if series:
                models = {series_label(r): r.get("model") for r in by_data[data] if r.get("table") == table}
                panels.append((ptitle, ylabel, series, models))
        if not panels:
            continue
        path = os.path.join(os.fspath(results_dir), f"bench_{_safe(data)}.png")
        _draw(panels, path, f"Error against transition length: {data}", dpi)
        out.append({"path": path, "data": data, "series": {p[0]: list(p[2]) for p in panels}})
    return out


def figures_markdown(rows: Sequence[dict], results_dir, dpi: int = 100) -> str:
    """Draw :func:`bench_figures` and return markdown linking them (relative to ``results_dir``), or ""."""
    try:
        figs = bench_figures(rows, results_dir, dpi=dpi)
    except (OSError, ValueError) as err:   # a figure must not cost the tables of a finished bench
        return f"Figures: not drawn ({err})."
    return "\n\n".join(f"Error against transition length, {f['data']}: "
                       f"[`{os.path.basename(f['path'])}`]({os.path.basename(f['path'])})\n\n"
                       f"![{f['data']}]({os.path.basename(f['path'])})" for f in figs)


def ratio_distribution(rows: Sequence[dict], path, title: str = "Per-window ratio to the base",
                       dpi: int = 100) -> dict | None:
    """Box plots of per-window ratios to each model's base, one panel per transition length.

    ``rows``: records with ``frames`` and a ``per_window`` list of ratios (model / its base, per test window),
    labelled as :func:`series_label`.  Non-finite ratios are dropped; a record with none left is left out; with
    no box to draw nothing is written and None returned.  A line at 1 marks the base.
    Returns ``{"path", "series": {frames: [labels drawn]}}``.
    """
    boxes: dict = {}
    for r in rows:
        vals = [float(v) for v in (r.get("per_window") or ()) if _finite(v)]
        if not vals or not _finite(r.get("frames")):
            continue
        boxes.setdefault(int(r["frames"]), {}).setdefault(series_label(r), []).extend(vals)
    if not boxes:
        return None
    lengths = sorted(boxes)
    width = max(3.0, 0.9 * max(len(b) for b in boxes.values()) + 1.5)
    fig = plt.figure(figsize=(width * len(lengths), 3.8), dpi=dpi, facecolor="white")
    try:
        for i, frames in enumerate(lengths):
            ax = fig.add_subplot(1, len(lengths), i + 1)
            labels = list(boxes[frames])
            ax.boxplot([boxes[frames][k] for k in labels], showfliers=True, widths=0.6)
            ax.set_xticks(range(1, len(labels) + 1))
            ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=7)
            ax.axhline(1.0, color="#555555", ls="--", lw=1.0)
            ax.set_title(f"{frames} frames", fontsize=10)
            ax.set_ylabel("ratio to base (per window)" if i == 0 else "")
            ax.grid(alpha=0.3, axis="y")
        fig.suptitle(title, fontsize=11)
        _save(fig, path, dpi, bbox_inches="tight")
    finally:
        plt.close(fig)
    return {"path": os.fspath(path), "series": {f: list(boxes[f]) for f in lengths}}


def calibration_figure(records: Sequence[dict], lo: float, hi: float, path, title: str, dpi: int = 100,
                       xlabel: str = "out-of-distribution score (k-NN distance / training median)"):
    """Error ratio against the out-of-distribution score, one point per validation window (``records`` of an
    ``ood_calibration.json``: ``score`` and ``ratios_at``, the last entry being the learned fill alone), with
    the gate's weight of the learned fill (1 below ``lo``, 0 above ``hi``) on a second axis.  Returns the path,
    or None when there are no records (nothing written)."""
    pts = [(float(r["score"]), float(r["ratios_at"][-1]), int(r.get("frames", 0))) for r in records
           if _finite(r.get("score")) and _finite(r["ratios_at"][-1])]
    if not pts:
        return None
    fig = plt.figure(figsize=(7.0, 4.2), dpi=dpi, facecolor="white")
    try:
        ax = fig.add_subplot(1, 1, 1)
        for n in sorted({p[2] for p in pts}):
            xs, ys = zip(*[(p[0], p[1]) for p in pts if p[2] == n])
            ax.scatter(xs, ys, s=9, alpha=0.6, label=f"{n} frames")
        ax.axhline(1.0, color="#555555", ls="--", lw=1.0)
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("error / base's (learned fill alone)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
        if math.isfinite(lo) and math.isfinite(hi):
            ax2 = ax.twinx()
            top = max(p[0] for p in pts)
            xs = [0.0, lo, hi, max(top, hi) * 1.05]
            ax2.plot(xs, [1, 1, 0, 0], color="black", lw=1.5)
            ax2.set_ylim(-0.05, 1.05)
            ax2.set_ylabel("gate: weight of the learned fill")
        ax.set_title(title, fontsize=10)
        _save(fig, path, dpi)
    finally:
        plt.close(fig)
    return os.fspath(path)


XLABELS = {"travel": "out-of-distribution score: 1 / (1 + keyframe root travel per frame / c)",
           "cae:travel": "out-of-distribution score: 1 / (1 + the root's floor speed beside the gap / c)",
           "speed": "out-of-distribution score: 1 / (1 + mean joint speed at the last known frame / (1 cm per frame))"}


def worst_case_figures(rows: Sequence[dict], results_dir, calibrations: dict | None = None, dpi: int = 100) -> str:
    """The per-window ratio distribution of every model (rows of table ``per_window``, group ``all``; one PNG per
    model, base and split) and the gate calibration figure of each ``calibrations`` entry (model -> path of an
    ``ood_calibration.json``); markdown linking them, or ""."""
    import json
    links = []
    try:
        keys = sorted({(r["model"], r["base"], r["split"]) for r in rows
                       if r.get("table") == "per_window" and r.get("group") == "all"})
        for model, base, split in keys:
            sel = [dict(r, method=f"{model} / {base}") for r in rows if r.get("table") == "per_window"
                   and r.get("group") == "all" and (r["model"], r["base"], r["split"]) == (model, base, split)]
            name = _safe(f"per_window_{model}_{base}_{split}") + ".png"
            if ratio_distribution(sel, os.path.join(results_dir, name), f"{model}: per-window error / {base}'s, "
                                  f"{split}", dpi=dpi):
                links.append(f"Per-window ratios, {model} / {base}, {split}: [`{name}`]({name})")
        for model, path in sorted((calibrations or {}).items()):
            if path and os.path.exists(path):
                with open(path) as f:
                    cal = json.load(f)
                name = f"ood_calibration_{model}.png"
                s = cal["summary"]
                label = XLABELS.get(f"{model}:{s.get('kind')}") or XLABELS.get(s.get("kind"))
                kw = {"xlabel": label} if label else {}
                if calibration_figure(cal["records"], s["lo"], s["hi"], os.path.join(results_dir, name),
                                      f"{model}: validation windows, error ratio against the OOD score", dpi=dpi,
                                      **kw):
                    links.append(f"Gate calibration, {model}: [`{name}`]({name})")
    except (OSError, ValueError, KeyError) as err:
        links.append(f"Worst-case figures: not drawn ({err}).")
    return "\n\n".join(links)
