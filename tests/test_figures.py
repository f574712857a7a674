"""The bench's figures (inbetween_jax/evaluation/figures.py), fed flat records as the benches write them."""
import math
import os

import numpy as np
import pytest
from PIL import Image

from inbetween_jax.evaluation import flat_rows
from inbetween_jax.evaluation import figures

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _rows(with_empty_model: bool = True) -> list:
    """Records of one embedded-CMU bench: baseline tables, a shipped S-CVAE, a CAE and an interaction section."""
    table1 = [{"method": m, "frames": f, "L2P": v, "L2Q": v / 9} for f, s, z in ((10, 2.25, 3.1), (30, 5.94, 7.0),
                                                                                 (50, 9.27, 10.2))
              for m, v in (("Slerp", s), ("Zero-velocity", z))]
    official = [{"method": "Slerp", "frames": f, "L2P": v} for f, v in ((5, 0.88), (15, 3.2), (30, 5.94), (45, 8.61))]
    rows = flat_rows(official, "official", "cmu-embedded") + flat_rows(table1, "table1", "cmu-embedded")
    scvae = flat_rows([{"method": "S-CVAE", "frames": f, "L2P": v} for f, v in ((10, 2.26), (30, 5.93), (50, 9.24))],
                      "table1", "embedded", model="scvae", variant="improved")
    scvae += flat_rows([{"method": "Slerp", "frames": 10, "L2P": 2.25}], "table1", "embedded", model="slerp")
    for r in scvae:
        r["weights"] = "shipped"
    cae = flat_rows([{"method": "linear", "frames": f, "gap_s": f / 30, "mpjpe_cm": v}
                     for f, v in ((0, 0.0), (30, 5.94), (60, 8.84), (120, 11.64))], "cae_table1", "embedded",
                    keys=("frames", "gap_s"))
    cae += flat_rows([{"method": "cae_residual", "frames": f, "gap_s": f / 30, "mpjpe_cm": v}
                      for f, v in ((30, 5.54), (60, 8.56), (120, 11.59))], "cae_table1", "embedded", "cae",
                     keys=("frames", "gap_s"))
    inter = flat_rows([{"frames": 30, "L2P": 3.29}, {"frames": 50, "L2P": 4.28}], "interaction_table1", "embedded",
                      model="interaction", variant="Ours (shipped)")
    inter += flat_rows([{"frames": 30, "L2P": 0.0}, {"frames": 50, "L2P": 0.0}], "interaction_table1", "embedded",
                       model="ground_truth")
    rows += scvae + cae + inter
    if with_empty_model:   # a model whose only numbers are not drawable: NaN, another metric, frames 0
        rows += [{"table": "table1", "data": "embedded", "model": "ghost", "variant": "x", "frames": 30,
                  "metric": "L2P", "value": math.nan},
                 {"table": "table1", "data": "embedded", "model": "ghost", "variant": "x", "frames": 30,
                  "metric": "NPSS", "value": 0.1},
                 {"table": "cae_table1", "data": "embedded", "model": "ghost", "variant": "x", "frames": 0,
                  "metric": "mpjpe_cm", "value": 1.0}]
    return rows


def _check_png(path, min_side=300, max_side=4000):
    with open(path, "rb") as fh:
        assert fh.read(8) == PNG_SIGNATURE
    assert os.path.getsize(path) > 5_000
    with Image.open(path) as im:
        im.verify()
    with Image.open(path) as im:
        w, h = im.size
        assert min_side <= w <= max_side and min_side <= h <= max_side, im.size
        return np.asarray(im.convert("RGB"))


def test_bench_figure_one_per_data_set(tmp_path):
    figs = figures.bench_figures(_rows(), tmp_path, dpi=60)
    assert [f["data"] for f in figs] == ["embedded"]   # cmu-embedded and embedded: one data set, one figure
    path = figs[0]["path"]
    assert path == os.path.join(str(tmp_path), "bench_embedded.png")
    img = _check_png(path)
    assert (img < 200).any() and (img == 255).all(-1).mean() > 0.3   # something drawn on a white page
    series = figs[0]["series"]
    assert list(series) == [p[2] for p in figures.PANELS]   # every panel of the records, in PANELS' order
    t1 = series[figures.PANELS[0][2]]
    assert t1 == ["Slerp", "Zero-velocity", "scvae (improved) [shipped]"]   # slerp of the scvae section: once
    assert series["CAE: gap filling"] == ["linear", "cae_residual"]
    assert series["Interaction: two characters"] == ["Ours (shipped)"]   # ground truth (all zero) left out
    assert not any("ghost" in label for labels in series.values() for label in labels)
    assert sorted(os.listdir(tmp_path)) == ["bench_embedded.png"]   # no temporary file left


def test_model_without_rows_draws_nothing(tmp_path):
    a = figures.bench_figures(_rows(with_empty_model=True), tmp_path / "a", dpi=60)
    b = figures.bench_figures(_rows(with_empty_model=False), tmp_path / "b", dpi=60)
    assert a[0]["series"] == b[0]["series"]
    assert np.array_equal(_check_png(a[0]["path"]), _check_png(b[0]["path"]))   # not even a legend entry


def test_no_drawable_rows_no_figure(tmp_path):
    rows = [{"table": "cae_table2", "data": "lafan1", "model": "cae", "variant": "cae", "corruption": "p=0.3",
             "metric": "mpjpe_cm", "value": 1.0},
            {"table": "table1", "data": "lafan1", "model": "Slerp", "variant": "", "frames": 10, "metric": "L2P",
             "value": float("inf")}]
    assert figures.bench_figures(rows, tmp_path) == []
    assert figures.figures_markdown(rows, tmp_path) == ""
    assert os.listdir(tmp_path) == []


def test_figures_markdown_links_each_png(tmp_path):
    rows = _rows() + flat_rows([{"method": "Slerp", "frames": 30, "L2P": 2.16}], "table1", "lafan1")
    md = figures.figures_markdown(rows, tmp_path, dpi=50)
    assert "(bench_embedded.png)" in md and "(bench_lafan1.png)" in md
    assert sorted(os.listdir(tmp_path)) == ["bench_embedded.png", "bench_lafan1.png"]


def _ratio_rows():
    rng = np.random.default_rng(0)
    rows = []
    for frames in (30, 50):
        for model, variant, centre in (("interaction", "Ours (shipped)", 0.9), ("scvae", "improved", 1.0)):
            rows.append({"table": "per_window", "data": "embedded", "model": model, "variant": variant,
                         "frames": frames, "metric": "L2P_ratio",
                         "per_window": list(centre + 0.1 * rng.standard_normal(40)) + [math.nan]})
        rows.append({"table": "per_window", "data": "embedded", "model": "ghost", "variant": "", "frames": frames,
                     "metric": "L2P_ratio", "per_window": []})
    rows.append({"table": "per_window", "data": "embedded", "model": "ghost", "variant": "", "frames": 70,
                 "metric": "L2P_ratio", "per_window": [math.nan]})
    return rows


def test_ratio_distribution(tmp_path):
    path = tmp_path / "ratios.png"
    out = figures.ratio_distribution(_ratio_rows(), path, dpi=60)
    assert out["path"] == str(path)
    assert out["series"] == {30: ["Ours (shipped)", "scvae (improved)"], 50: ["Ours (shipped)", "scvae (improved)"]}
    _check_png(path, min_side=150)


def test_ratio_distribution_nothing_to_draw(tmp_path):
    rows = [r for r in _ratio_rows() if r["model"] == "ghost"]
    assert figures.ratio_distribution(rows, tmp_path / "r.png") is None
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("name,canon", [("cmu-embedded", "embedded"), ("bvh-folder", "bvh"), ("lafan1", "lafan1")])
def test_canonical_data(name, canon):
    assert figures.canonical_data(name) == canon
