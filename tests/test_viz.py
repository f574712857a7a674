"""Previews (contact sheets, GIFs, error plots) drawn from the shipped CMU motions."""
import importlib.util
import os

import matplotlib.image as mpimg
import numpy as np
import pytest
from PIL import Image

from inbetween_jax import viz
from inbetween_jax.cli import main
from inbetween_jax.data import load_motions
from inbetween_jax.data.datasets import EMBEDDED_DIR
from inbetween_jax.geometry import forward_kinematics

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
DPI = 40


@pytest.fixture(scope="module")
def clips():
    """Global positions (T, J, 3) of the first two embedded test motions, and their parents."""
    motions = load_motions("embedded", "test")[:2]
    out = []
    for m in motions:
        _, pos = forward_kinematics(m.local_quats, m.local_pos, m.skeleton.parents)
        out.append((pos, m.skeleton.parents))
    return out


def _rgb255(path):
    img = mpimg.imread(path)
    return np.round(img[..., :3] * 255).astype(int)


def _count(rgb, hex_color, tol=2):
    target = np.array([int(hex_color[i:i + 2], 16) for i in (1, 3, 5)])
    return int(np.all(np.abs(rgb - target) <= tol, axis=-1).sum())


def test_contact_sheet_png_and_colours(clips, tmp_path):
    pos, parents = clips[0]
    pos = pos[:40]
    generated = np.zeros(40, bool)
    generated[1:30] = True
    path = tmp_path / "new" / "folder" / "sheet.png"
    assert viz.contact_sheet(pos, parents, path, every=5, keyframes=(0, 30), generated=generated,
                             title="13_10", dpi=DPI) == str(path)
    with open(path, "rb") as fh:
        assert fh.read(8) == PNG_SIGNATURE
    assert os.listdir(path.parent) == ["sheet.png"]  # the temporary file was renamed, not left behind
    rgb = _rgb255(path)
    h, w = rgb.shape[:2]
    assert h == round((2.5 + 0.3) * DPI)
    assert w > 3 * h  # 8 poses side by side
    assert _count(rgb, viz.KEY_COLOR) > 50
    assert _count(rgb, viz.GENERATED_COLOR) > 50
    assert _count(rgb, viz.OTHER_COLOR) > 20  # frames 30..39 are neither key nor generated


def test_contact_sheet_grey_only_for_generated_and_black_only_for_keys(clips, tmp_path):
    pos, parents = clips[0]
    pos = pos[:30]
    rgb = _rgb255(viz.contact_sheet(pos, parents, tmp_path / "a.png", every=5, keyframes=(0, 29), dpi=DPI))
    assert _count(rgb, viz.KEY_COLOR) > 50
    assert _count(rgb, viz.GENERATED_COLOR) == 0
    rgb = _rgb255(viz.contact_sheet(pos, parents, tmp_path / "b.png", every=5, dpi=DPI))
    assert _count(rgb, viz.KEY_COLOR) == 0
    assert _count(rgb, viz.OTHER_COLOR) > 50


def test_gif_frame_counts(clips, tmp_path):
    (pos, parents), (pos_b, parents_b) = clips
    t = 12
    path = viz.animate(pos[:t], parents, tmp_path / "one.gif", keyframes=(0, 5), size=2.0, dpi=40)
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == t
        im.seek(5)  # keyframe: bones black and thick
        dark_key = int((np.asarray(im.convert("L")) < 60).sum())
        im.seek(6)
        dark_other = int((np.asarray(im.convert("L")) < 60).sum())
    assert dark_key > dark_other + 30
    path = viz.animate(pos[:t], parents, tmp_path / "two.gif", positions_b=pos_b[:t], parents_b=parents_b,
                       stride=5, size=2.0, dpi=40)
    with Image.open(path) as im:
        assert im.n_frames == len(range(0, t, 5)) == 3
    path = viz.animate(pos[:t], parents, tmp_path / "three.gif", view="3d", stride=4, size=2.0, dpi=40)
    with Image.open(path) as im:
        assert im.n_frames == 3
    assert sorted(os.listdir(tmp_path)) == ["one.gif", "three.gif", "two.gif"]


@pytest.mark.parametrize("case, message", [
    ("joints", "positions have 20 joints but the skeleton has 21"),
    ("nan", "positions contain NaN at frame 3"),
    ("inf", "positions contain inf at frame 7"),
    ("shape", r"positions must have shape \(T, J, 3\)"),
    ("keyframe", "keyframe 99 is outside the 10 frames"),
    ("generated", r"generated must be a \(10,\) bool array"),
])
def test_invalid_inputs_raise_and_write_nothing(clips, tmp_path, case, message):
    pos, parents = clips[0]
    pos = np.array(pos[:10])
    kwargs = {}
    if case == "joints":
        pos = pos[:, :-1]
    elif case == "nan":
        pos[3, 4, 1] = np.nan
    elif case == "inf":
        pos[7, 0, 0] = np.inf
    elif case == "shape":
        pos = pos[..., :2]
    elif case == "keyframe":
        kwargs["keyframes"] = (0, 99)
    else:
        kwargs["generated"] = np.ones(9, bool)
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=message):
        viz.contact_sheet(pos, parents, out / "s.png", **kwargs)
    kwargs.pop("generated", None)
    if case != "generated":
        with pytest.raises(ValueError, match=message):
            viz.animate(pos, parents, out / "a.gif", **kwargs)
    assert not out.exists()


def test_animate_rejects_mismatched_second_character(clips, tmp_path):
    (pos, parents), (pos_b, parents_b) = clips
    with pytest.raises(ValueError, match="positions_b have 5 frames but positions have 10"):
        viz.animate(pos[:10], parents, tmp_path / "x.gif", positions_b=pos_b[:5], parents_b=parents_b)
    with pytest.raises(ValueError, match="positions_b have 20 joints but the skeleton has 21"):
        viz.animate(pos[:10], parents, tmp_path / "x.gif", positions_b=pos_b[:10, :-1])
    assert os.listdir(tmp_path) == []


def test_error_over_time_plot(clips, tmp_path):
    """Per-frame error of linear interpolation and of holding the first keyframe over real 31-frame windows."""
    pos, _ = clips[0]
    n = 30
    windows = np.stack([pos[s:s + n + 1] for s in range(0, pos.shape[0] - n, 15)])  # (W, n+1, J, 3)
    w = (np.arange(n + 1) / n)[None, :, None, None]
    lerp = (1 - w) * windows[:, :1] + w * windows[:, -1:]
    err = np.linalg.norm(lerp - windows, axis=-1).mean(-1)                          # (W, n+1)
    hold = np.linalg.norm(windows[:, :1] - windows, axis=-1).mean(-1).mean(0)
    assert err[:, 0].max() < 1e-9 and err[:, -1].max() < 1e-9 and err.max() > 1.0
    path = viz.plot_error_over_time(np.arange(n + 1), err.mean(0), err.min(0), err.max(0),
                                    tmp_path / "plots" / "err.png", "interpolation",
                                    baseline={"zero velocity": hold}, ylabel="mean joint error (cm)", dpi=40)
    with open(path, "rb") as fh:
        assert fh.read(8) == PNG_SIGNATURE
    assert mpimg.imread(path).shape[:2] == (round(3.2 * 40), 5 * 40)
    with pytest.raises(ValueError, match="lo > hi at index"):
        viz.plot_error_over_time(np.arange(n + 1), err.mean(0), err.max(0), err.min(0), tmp_path / "bad.png", "x")
    with pytest.raises(ValueError, match="has 3 values but times has 31"):
        viz.plot_error_over_time(np.arange(n + 1), err.mean(0), err.min(0), err.max(0), tmp_path / "bad.png",
                                 "x", baseline={"short": hold[:3]})
    assert not (tmp_path / "bad.png").exists()


def test_preview_command(tmp_path, capsys):
    """``inbetween preview`` (and its thin wrapper ``experiments/preview.py``): PNG + GIF, one-line errors."""
    out = tmp_path / "out"
    bvh = os.path.join(EMBEDDED_DIR, "02_01.bvh")
    argv = [bvh, "--frames", "10:25", "--every", "5", "--keyframes", "10,24", "--out", str(out), "--gif"]
    assert main(["preview"] + argv) == 0
    assert sorted(os.listdir(out)) == ["02_01.gif", "02_01_sheet.png"]
    with open(out / "02_01_sheet.png", "rb") as fh:
        assert fh.read(8) == PNG_SIGNATURE
    with Image.open(out / "02_01.gif") as im:
        assert im.n_frames == 15
    assert capsys.readouterr().out.split() == [str(out / "02_01_sheet.png"), str(out / "02_01.gif")]

    spec = importlib.util.spec_from_file_location("preview", os.path.join(ROOT, "experiments", "preview.py"))
    wrapper = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(wrapper)
    assert wrapper.main([bvh, "--frames=-12:", "--out", str(tmp_path / "wrapped")]) == 0
    assert os.listdir(tmp_path / "wrapped") == ["02_01_sheet.png"]
    capsys.readouterr()

    with open(bvh) as fh:
        lines = fh.read().splitlines()
    bad = tmp_path / "broken.bvh"
    bad.write_text("\n".join(lines[:-5]) + "\n")  # header promises 86 frames, 81 remain
    cases = [([str(bad), "--gif"], ("broken.bvh", "truncated MOTION block")),
             ([bvh, "--frames", "200:300"], ("select none of its 86 frames",)),
             ([bvh, "--frames", "10:20", "--keyframes", "5"], ("must lie in the selected frames [10, 20)",)),
             ([bvh, "--frames", "1-2"], ("expected a:b",)),
             ([bvh, "--keyframes", "a,b"], ("expected comma-separated frame numbers",)),
             ([bvh, "--every", "0"], ("--every must be >= 1",))]
    for args, phrases in cases:
        bad_out = tmp_path / "bad_out"
        assert main(["preview"] + args + ["--out", str(bad_out)]) == 2, args
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("inbetween: error: ") and all(p in err[0] for p in phrases), err
        assert not bad_out.exists()
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]    # no temporary folder left behind
