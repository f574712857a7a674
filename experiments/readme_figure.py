"""The README's status figure: each model's error as a ratio to its base, against transition length.

`python experiments/readme_figure.py [OUT.png]` (default docs/figures/status.png) reads the numbers from the "Current
results" tables of docs/results/{scvae,cae,interaction}.md: the rows named in ROWS below (matched by the start of the
row), ratios written "0.842x" in them; no number is typed in here.
"""
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COLORS = {"CMU test subjects": "C0", "CMU held-out subjects": "C1", "LaFAN1 subset": "C2"}   # else C3, C4, ...
SHIP, BEST, S3, S2 = "| **shipped weights**", "| **best recipe", slice(0, 3), slice(0, 2)
# page, x values (frames), base, target, [(label, row start, which ratios of the row, line style)]
ROWS = [
    ("scvae", (10, 30, 50), "Slerp", 0.85, [
        ("CMU test subjects, shipped", SHIP, S3, "-"), ("LaFAN1 subset, best recipe", BEST, S3, "-"),
        ("CMU held-out subjects, shipped (per window)", "| held out: the same behind its gate", S3, "-"),
        ("CMU held-out subjects, network alone", "| held out: `improved` on", S3, "--"),
        ("CMU test subjects, cpu", "| `cpu` (paper", S3, ":"), ("LaFAN1 subset, cpu", "| `cpu` (earlier", S3, ":")]),
    ("cae", (30, 60, 120), "linear fill", 0.85, [
        ("CMU test subjects, shipped", SHIP, S3, "-"), ("LaFAN1 subset, best recipe", BEST, S3, "-"),
        ("CMU test subjects, cpu", "| `cpu` (paper's method; the run", S3, ":"),
        ("LaFAN1 subset, cpu", "| `cpu` (paper's method) |", S3, ":")]),
    ("interaction", (30, 50), "interpolation", 0.9, [
        ("salsa test takes, shipped, true gap", SHIP, S2, "-"), ("shipped, gap guessed", SHIP, slice(2, 4), "-"),
        ("improved (1 network)", "| `improved`, one network", S2, "-"),
        ("cpu (quick bench, 24 windows)", "| `cpu` (paper's method;", S2, ":")]),
]


def ratios(page: str, start: str, which: slice) -> list:
    with open(os.path.join(ROOT, "docs", "results", f"{page}.md")) as fh:
        row = next(line for line in fh if line.startswith(start))   # the first such row: the "Current results" one
    return [float(v) for v in re.findall(r"(\d+\.\d+)x\b", row)][which]


def main(out: str) -> None:
    fig, axes = plt.subplots(1, len(ROWS), figsize=(13, 3.8), facecolor="white")
    for ax, (page, xs, base, target, rows) in zip(axes, ROWS):
        for i, (label, start, which, ls) in enumerate(rows):
            ys = ratios(page, start, which)   # matplotlib refuses a row with fewer ratios than lengths
            ax.plot(xs, ys, ls=ls, marker="o", lw=2, label=label, color=COLORS.get(label.split(",")[0], f"C{i + 3}"))
        ax.axhline(1.0, color="black", lw=1)
        ax.axhline(target, color="grey", lw=1, ls="--")
        ax.set(yscale="log", title=f"{page}: error / {base}", xlabel="transition length (frames)", xticks=xs,
               ylabel="ratio to base (log; dashed: target)")
        ax.set_yticks([0.7, 0.85, 0.9, 1, 1.5, 2, 3], ["0.7", "0.85", "", "1", "1.5", "2", "3"])
        ax.legend(fontsize=7, frameon=False)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    fig.savefig(out, dpi=90, facecolor="white")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "figures", "status.png"))
