"""Previews (contact sheets, GIFs, error plots) drawn from the shipped CMU motions."""
import dataclasses
import os

import matplotlib.image as mpimg
import numpy as np
import pytest
from PIL import Image

from inbetween_jax import viz
from inbetween_jax.cli import main
from inbetween_jax.data import load_motions, read_bvh, write_bvh
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

    assert main(["preview", bvh, "--frames=-12:", "--out", str(tmp_path / "tail")]) == 0
    assert os.listdir(tmp_path / "tail") == ["02_01_sheet.png"]
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


# ------------------------------------------------------------------ bounded work, GIF timing, interrupts
def _gif_delays(path):
    """(frame count, [delay ms of each frame]) read back with Pillow."""
    with Image.open(path) as im:
        delays = []
        for k in range(im.n_frames):
            im.seek(k)
            delays.append(im.info["duration"])
        return im.n_frames, delays


def _progress_log():
    calls = []
    return calls, lambda done, total: calls.append((done, total))


@pytest.mark.parametrize("hz", [30, 120])
def test_gif_plays_as_long_as_the_motion(tmp_path, hz):
    """A real clip, as recorded (30 Hz) and with its frames played at 120 Hz: integer stride to <= 30 fps,
    delays of 20 ms or more adding up to the motion's duration (within 5 %), read back with Pillow."""
    motion = read_bvh(os.path.join(EMBEDDED_DIR, "02_01.bvh"))
    if hz != 30:
        motion = dataclasses.replace(motion, frame_time=1.0 / hz)
    pos, t = viz.motion_positions(motion), motion.num_frames
    calls, progress = _progress_log()
    path = viz.animate(pos, motion.skeleton.parents, tmp_path / "m.gif", fps=motion.fps, size=2.0, dpi=40,
                       progress=progress)
    stride = {30: 1, 120: 4}[hz]                          # 30 Hz file: frame time 0.03333332 s, every frame
    n, delays = _gif_delays(path)
    assert n == len(range(0, t, stride)) and min(delays) >= 20
    assert abs(sum(delays) / 1000.0 - t / motion.fps) <= 0.05 * t / motion.fps
    assert abs(n / (sum(delays) / 1000.0) - motion.fps / stride) <= 0.05 * motion.fps / stride
    assert calls == [(k, n + 1) for k in range(1, n + 2)]


def test_frame_plans_are_bounded():
    """Pure arithmetic of the frame choices (no drawing)."""
    for t, fps in [(20000, 120.0), (86, 1 / 0.03333332), (1000, 60.0), (1000, 100.0), (7, 120.0), (1, 24.0)]:
        plan = viz.gif_frames(t, fps)
        assert len(plan.frames) <= viz.MAX_GIF_FRAMES and plan.frames == list(range(0, t, plan.stride))
        assert fps / plan.stride <= viz.MAX_GIF_FPS * 1.01 and min(plan.durations_ms) >= 20
        assert all(d % 10 == 0 for d in plan.durations_ms)
        assert abs(sum(plan.durations_ms) - 1000.0 * t / fps) <= 5 + 20 * (t / fps < 0.25)
    assert [viz.gif_frames(300, f).stride for f in (1 / 0.03333332, 50.0, 60.0, 100.0, 120.0)] == [1, 2, 2, 4, 4]
    assert viz.gif_frames(20000, 120.0).stride == 50 and "every 50th frame" in viz.gif_frames(20000, 120.0).note
    assert viz.gif_frames(100, 30.0, stride=3).stride == 3 and viz.gif_frames(100, 30.0, stride=3).note == ""

    plan = viz.sheet_frames(20000, every=5)
    assert plan.step == 500 and len(plan.frames) == 40 and "every 500th of 20000 frames" in plan.note
    plan = viz.sheet_frames(40, every=5, keyframes=(0, 30))
    assert plan.frames == [0, 5, 10, 15, 20, 25, 30, 35] and plan.note == ""
    keys = list(range(3, 20000, 97))                        # 207 keyframes: a long infill with many gaps
    plan = viz.sheet_frames(20000, every=1250, keyframes=keys)
    assert len(plan.frames) <= viz.MAX_POSES and set(plan.keyframes) <= set(keys) and len(plan.keyframes) == 20
    assert plan.keyframes[0] == 3 and plan.keyframes[-1] == keys[-1] and "20 of 207 keyframes" in plan.note


@pytest.fixture(scope="module")
def long_bvh(tmp_path_factory):
    """~20,000 frames at 120 Hz: a shipped CMU clip played forwards and backwards (real frames, no jumps)."""
    motion = read_bvh(os.path.join(EMBEDDED_DIR, "05_01.bvh"))
    order = np.resize(np.r_[np.arange(motion.num_frames), np.arange(motion.num_frames - 2, 0, -1)], 20000)
    long = dataclasses.replace(motion, local_quats=motion.local_quats[order], local_pos=motion.local_pos[order],
                               frame_time=1.0 / 120.0)
    path = tmp_path_factory.mktemp("long") / "long.bvh"
    write_bvh(path, long)
    return str(path)


def _pose_columns(rgb, hex_color):
    """Number of runs of image columns holding ``hex_color`` (poses spread evenly never share a column)."""
    cols = np.any(np.all(np.abs(rgb - [int(hex_color[i:i + 2], 16) for i in (1, 3, 5)]) <= 2, -1), 0)
    return int(np.sum(cols[1:] & ~cols[:-1]) + cols[0])


def test_long_file_sheet_is_bounded(long_bvh, tmp_path):
    """The 20,000-frame file: the sheet draws 40 poses (every 500th frame, said in the title), not 4,000."""
    motion = read_bvh(long_bvh)
    assert motion.num_frames == 20000 and abs(motion.fps - 120.0) < 1e-3
    calls, progress = _progress_log()
    files = viz.bvh_previews(motion, "long", every=5, progress=progress)
    assert list(files) == ["long_sheet.png"]
    files["long_sheet.png"](str(tmp_path / "long_sheet.png"))
    assert calls[-1] == (41, 41) and len(calls) == 41          # 40 poses, then the save
    rgb = _rgb255(tmp_path / "long_sheet.png")
    assert rgb.shape[0] == round((2.5 + 0.3) * 100)               # a title line: the note
    assert _pose_columns(rgb, viz.OTHER_COLOR) == 40


@pytest.mark.slow
def test_long_file_preview_command(long_bvh, tmp_path, capsys):
    """``inbetween preview --gif`` of the 20,000-frame file: 400 GIF frames (every 50th), 410-420 ms each,
    166.7 s in all like the motion; 40 poses on the sheet."""
    out = tmp_path / "out"
    assert main(["preview", long_bvh, "--gif", "--out", str(out)]) == 0
    assert sorted(os.listdir(out)) == ["long.gif", "long_sheet.png"]
    n, delays = _gif_delays(out / "long.gif")
    assert n == 400 == len(range(0, 20000, 50)) and set(delays) == {410, 420}
    assert abs(sum(delays) / 1000.0 - 20000 / 120.0) <= 0.05 * 20000 / 120.0
    assert _pose_columns(_rgb255(out / "long_sheet.png"), viz.OTHER_COLOR) == 40
    capsys.readouterr()


def test_interrupt_leaves_destination_untouched(clips, tmp_path):
    """Ctrl-C (KeyboardInterrupt) while drawing or while writing: the old file stays, no temporary file is left;
    files are created 0644 less the umask."""
    pos, parents = clips[0]
    dest = tmp_path / "m.gif"
    dest.write_bytes(b"old")

    def stop_at_3(done, total):
        if done == 3:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        viz.animate(pos[:20], parents, dest, size=2.0, dpi=40, progress=stop_at_3)
    with pytest.raises(KeyboardInterrupt):
        viz.contact_sheet(pos[:20], parents, tmp_path / "m.gif", dpi=DPI, progress=stop_at_3)

    def half_then_stop(fh):
        fh.write(b"GIF89a" + b"\0" * 1000)
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        viz.save_atomic(dest, half_then_stop, ".gif")
    assert dest.read_bytes() == b"old" and os.listdir(tmp_path) == ["m.gif"]

    old = os.umask(0o022)
    try:
        viz.contact_sheet(pos[:20], parents, tmp_path / "a.png", dpi=DPI)
        os.umask(0o027)
        viz.animate(pos[:5], parents, tmp_path / "b.gif", size=2.0, dpi=40)
    finally:
        os.umask(old)
    assert os.stat(tmp_path / "a.png").st_mode & 0o777 == 0o644
    assert os.stat(tmp_path / "b.gif").st_mode & 0o777 == 0o640
    assert sorted(os.listdir(tmp_path)) == ["a.png", "b.gif", "m.gif"]
