"""Previews of motions: contact sheets and animated GIFs (matplotlib, Agg); error-over-time plots: :mod:`.viz_plots`.

Conventions: ``positions`` are (T, J, 3) global joint positions in cm, Y up, floor on the XZ plane;
``parents`` is the skeleton's parent array (``parents[0] == -1``, ``parents[j] < j``).
Every writer validates its inputs first (``ValueError`` with a one-line message, nothing written),
creates the output folder if needed, writes to a temporary file beside ``path`` and renames it into
place, and returns ``path``.  :func:`preview_writers` / :func:`bvh_previews` (used by the ``inbetween``
command) check a motion's inputs up front and return such writers for files named after the motion.
The work is bounded whatever the length of the motion: a contact sheet draws at most ``max_poses``
poses and a GIF has at most ``max_frames`` frames at most ``max_fps`` frames per second (see
:func:`sheet_frames` and :func:`gif_frames`).  Writers take an optional ``progress(done, total)``
callback, called as the drawing advances.
"""
from __future__ import annotations

import os
from typing import Optional, Sequence

import matplotlib

matplotlib.use("Agg")  # no screen: never pick an interactive backend from the environment
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

from inbetween_jax.viz_frames import (MAX_GIF_FPS, MAX_GIF_FRAMES, MAX_POSES, GifPlan,  # noqa: E402,F401
                                      GifPalette, Progress, SheetPlan, canvas_rgb, gif_frames, save_atomic,
                                      sheet_frames, write_gif)
from inbetween_jax.viz_plots import plot_error_over_time  # noqa: E402,F401

KEY_COLOR = "#000000"        # keyframes
GENERATED_COLOR = "#999999"  # generated (in-between) frames
OTHER_COLOR = "#1f77b4"      # frames that are neither (context / ground truth)
OTHER_COLOR_B = "#d62728"    # second character
FLOOR_COLOR = "#d9d9d9"


# ----------------------------------------------------------------------------------------- checks
def _check_parents(parents) -> tuple:
    try:
        par = tuple(int(p) for p in parents)
    except (TypeError, ValueError):
        raise ValueError("parents must be a sequence of ints") from None
    if not par or par[0] != -1 or any(not (p == -1 or 0 <= p < j) for j, p in enumerate(par) if j > 0):
        raise ValueError("parents must have parents[0] == -1 and 0 <= parents[j] < j (or -1: another root)")
    return par


def _check_positions(positions, parents, name: str = "positions"):
    """-> ((T, J, 3) float64 array, parents tuple); ValueError naming the first problem."""
    par = _check_parents(parents)
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (T, J, 3), got {pos.shape}")
    if pos.shape[0] == 0:
        raise ValueError(f"{name} have no frames")
    if pos.shape[1] != len(par):
        raise ValueError(f"{name} have {pos.shape[1]} joints but the skeleton has {len(par)}")
    bad = ~np.isfinite(pos)
    if bad.any():
        t, j, _ = np.argwhere(bad)[0]
        what = "NaN" if np.isnan(pos[t, j]).any() else "inf"
        raise ValueError(f"{name} contain {what} at frame {t} (joint {j})")
    return pos, par


def _check_keyframes(keyframes, num_frames: int) -> list:
    keys = sorted({int(k) for k in keyframes})
    out = [k for k in keys if not 0 <= k < num_frames]
    if out:
        raise ValueError(f"keyframe {out[0]} is outside the {num_frames} frames")
    return keys


def _check_generated(generated, num_frames: int) -> np.ndarray:
    gen = np.asarray(generated)
    if gen.shape != (num_frames,) or gen.dtype != bool:
        raise ValueError(f"generated must be a ({num_frames},) bool array, got {gen.dtype} {gen.shape}")
    return gen


# ------------------------------------------------------------------------------------ geometry
def _heading(points_xz: np.ndarray) -> np.ndarray:
    """Unit XZ direction of the overall motion of a (T, 2) trajectory (principal axis if it barely moves)."""
    d = points_xz[-1] - points_xz[0]
    if np.linalg.norm(d) < 1.0:
        centred = points_xz - points_xz.mean(0)
        if np.abs(centred).max(initial=0.0) < 1e-6:
            return np.array([1.0, 0.0])
        d = np.linalg.svd(centred, full_matrices=False)[2][0]
    return d / np.linalg.norm(d)


def _side_view(pos: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(..., J, 3) -> (..., J, 2): (coordinate along ``u`` on the floor, height)."""
    return np.stack([pos[..., 0] * u[0] + pos[..., 2] * u[1], pos[..., 1]], axis=-1)


def _bones(parents) -> list:
    return [(p, j) for j, p in enumerate(parents) if p >= 0]


def _segments(pose: np.ndarray, parents, r: float = 4.0) -> np.ndarray:
    """(B, 2, 2) line segments of a 2-D pose (J, 2): its bones, and a cross of half-size ``r`` (cm) on every
    joint without a bone (a one-joint rig), so that it shows."""
    segs = pose[np.array(_bones(parents), int).reshape(-1, 2)]
    lone = [j for j, p in enumerate(parents) if p < 0 and j not in parents]
    cross = np.array([[[-r, 0.0], [r, 0.0]], [[0.0, -r], [0.0, r]]])
    return np.concatenate([segs] + [pose[j] + cross for j in lone])


# ---------------------------------------------------------------------------------- public API
def sheet_canvas(xy, width: float, height: float, dpi: int, titled: bool):
    """``(figure, axes, ymin)`` of a contact sheet of side-view poses ``xy`` (..., J, 2) (cm): the poses' x range
    with a margin of 0.1 ``width``, room below the floor for frame numbers, equal aspect, the floor drawn; a
    ``titled`` sheet is 0.3 inch taller.  The caller closes the figure."""
    xmin, xmax = xy[..., 0].min() - 0.1 * width, xy[..., 0].max() + 0.1 * width
    ymin, ymax = min(0.0, xy[..., 1].min()) - 16.0, xy[..., 1].max() + 10.0  # room for frame numbers
    fig_w = min(max(height * (xmax - xmin) / (ymax - ymin), 2.0), 60.0)
    head = 0.3 if titled else 0.0
    fig = plt.figure(figsize=(fig_w, height + head), dpi=dpi, facecolor="white")
    ax = fig.add_axes((0.0, 0.0, 1.0, height / (height + head)))
    ax.set_axis_off()
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal", adjustable="box")
    ax.plot([xmin, xmax], [0.0, 0.0], color=FLOOR_COLOR, lw=1.0, zorder=0)
    return fig, ax, ymin


def contact_sheet(positions, parents, path, every: int = 5, keyframes: Sequence[int] = (),
                  title: Optional[str] = None, generated=None, *, height: float = 2.5, dpi: int = 100,
                  first_frame: int = 0, max_poses: int = MAX_POSES, progress: Progress = None) -> str:
    """Stick figures of every ``every``-th frame (plus every keyframe) side by side, as a PNG.

    positions: (T, J, 3) global positions (cm, Y up); parents: (J,) parent array.
    keyframes: frame indices drawn in black; generated: optional (T,) bool, True frames drawn grey;
    other frames are drawn blue. The view is from the side with the overall motion going left to
    right; poses keep their place along the path unless they would overlap, then they are spread
    evenly. ``height`` (inches) and ``dpi`` set the image size; ``first_frame`` only shifts the
    frame numbers printed under the poses. At most ``max_poses`` poses are drawn: when ``every``
    (or the keyframes) would give more, the step grows (:func:`sheet_frames`) and the title says so.
    ``progress(done, total)`` is called after each pose and after saving. Returns ``path``.
    """
    pos, par = _check_positions(positions, parents)
    t = pos.shape[0]
    if int(every) < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    keys = _check_keyframes(keyframes, t)
    gen = np.zeros(t, bool) if generated is None else _check_generated(generated, t)
    plan = sheet_frames(t, int(every), keys, max_poses)
    frames, keys = plan.frames, set(plan.keyframes)
    title = " ".join(x for x in (title, plan.note) if x) or None

    u = _heading(pos[:, 0, [0, 2]])
    xy = _side_view(pos[frames], u)                          # (F, J, 2)
    root_x = xy[:, 0, 0].copy()
    local_x = xy[..., 0] - root_x[:, None]
    width = max(float(np.ptp(xy[..., 0], axis=1).max()), 20.0)
    gaps = np.diff(root_x)
    if len(frames) > 1 and gaps.min() < 0.9 * width:          # would overlap: spread evenly
        root_x = np.arange(len(frames)) * 1.15 * width
    xy[..., 0] = local_x + root_x[:, None]

    total = len(frames) + 1
    style = {"lines.antialiased": False, "text.antialiased": False, "patch.antialiased": False}
    with plt.rc_context(style):
        fig, ax, ymin = sheet_canvas(xy, width, height, dpi, bool(title))
        try:
            for f, (frame, pose) in enumerate(zip(frames, xy)):
                is_key = frame in keys
                color = KEY_COLOR if is_key else GENERATED_COLOR if gen[frame] else OTHER_COLOR
                ax.add_collection(LineCollection(_segments(pose, par), colors=color, linewidths=2.0 if is_key else 1.5,
                                                 capstyle="round", antialiaseds=False, zorder=2 if is_key else 1),
                                  autolim=False)
                if is_key:
                    ax.text(root_x[f], ymin + 1.0, str(frame + first_frame), ha="center", va="bottom",
                            fontsize=7, color=KEY_COLOR)
                if progress is not None:
                    progress(f + 1, total)
            if title:
                fig.suptitle(title, fontsize=9, y=0.99, va="top")
            save_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=dpi, facecolor="white"), ".png")
        finally:
            plt.close(fig)
    if progress is not None:
        progress(total, total)
    return os.fspath(path)


def animate(positions, parents, path, fps: float = 30, keyframes: Sequence[int] = (),
            positions_b=None, parents_b=None, *, stride: int = 1, view: str = "side", size: float = 3.0,
            dpi: int = 80, first_frame: int = 0, max_fps: float = MAX_GIF_FPS,
            max_frames: int = MAX_GIF_FRAMES, progress: Progress = None) -> str:
    """Animated GIF of one character, or two (interaction) when ``positions_b`` is given.

    positions: (T, J, 3) sampled at ``fps``; positions_b: optional (T, Jb, 3) on ``parents_b``
    (default: ``parents``). Frames 0, s, 2s, ... are drawn, ``s`` being the smallest integer stride
    >= ``stride`` that plays at most ``max_fps`` frames per second and gives at most ``max_frames``
    frames (:func:`gif_frames`); the frame delays (whole centiseconds) add up to the motion's duration
    ``T / fps``. Keyframes are drawn black and thicker, with "key" in the caption.
    view: ``"side"`` (2-D, horizontal axis along the motion, or across the two characters) or
    ``"3d"``. ``size`` (inches, square) and ``dpi`` set the image size.
    ``progress(done, total)`` is called after each frame and after saving. Returns ``path``.
    """
    pos, par = _check_positions(positions, parents)
    t = pos.shape[0]
    chars = [(pos, par, OTHER_COLOR)]
    if positions_b is not None:
        pos_b, par_b = _check_positions(positions_b, parents if parents_b is None else parents_b, "positions_b")
        if pos_b.shape[0] != t:
            raise ValueError(f"positions_b have {pos_b.shape[0]} frames but positions have {t}")
        chars.append((pos_b, par_b, OTHER_COLOR_B))
    if view not in ("side", "3d"):
        raise ValueError(f"view must be 'side' or '3d', got {view!r}")
    if int(stride) < 1 or not fps > 0:
        raise ValueError(f"stride must be >= 1 and fps > 0, got stride={stride}, fps={fps}")
    keys = set(_check_keyframes(keyframes, t))
    plan = gif_frames(t, float(fps), int(stride), max_fps=max_fps, max_frames=max_frames)

    allpos = np.concatenate([c[0] for c in chars], axis=1)   # (T, J+Jb, 3)
    if len(chars) == 2:
        u = _heading(np.stack([pos[0, 0, [0, 2]], chars[1][0][0, 0, [0, 2]]]))
    else:
        u = _heading(pos[:, 0, [0, 2]])
    fig = plt.figure(figsize=(size, size), dpi=dpi, facecolor="white")
    try:
        if view == "3d":
            ax = fig.add_subplot(projection="3d")
            lo, hi = allpos.min((0, 1)), allpos.max((0, 1))
            mid, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 50.0)
            ax.set_xlim(mid[0] - half, mid[0] + half)
            ax.set_ylim(-mid[2] - half, -mid[2] + half)  # matplotlib's z is up: plot (x, -z, y),
            ax.set_zlim(0.0, 2 * half)                      # which keeps the axes right-handed
            ax.set_xlabel("x")
            ax.set_ylabel("-z")
            ax.set_zlabel("y")
            data = [c[0][..., [0, 2, 1]] * np.array([1.0, -1.0, 1.0]) for c in chars]
        else:
            ax = fig.add_subplot()
            proj = _side_view(allpos, u)
            xmin, xmax = proj[..., 0].min() - 20.0, proj[..., 0].max() + 20.0
            ymax = proj[..., 1].max() + 20.0
            ax.set_xlim(xmin, xmax)
            ax.set_ylim(min(0.0, proj[..., 1].min()) - 10.0, ymax)
            ax.set_aspect("equal", adjustable="box")
            ax.axhline(0.0, color=FLOOR_COLOR, lw=1.0, zorder=0)
            ax.set_xticks([])
            ax.set_yticks([])
            data = [_side_view(c[0], u) for c in chars]
        # The figure is drawn once; each frame then redraws only the bones and the caption on a copy of
        # that background (blitting): a short call per frame, so Ctrl-C stops between frames.
        if view == "3d":
            artists = [[ax.plot([], [], [], lw=2.0, color=col, animated=True)[0] for _ in _bones(p)]
                       for (_, p, col) in chars]
        else:
            artists = [ax.add_collection(LineCollection([], colors=col, linewidths=2.0, animated=True),
                                         autolim=False) for (_, _, col) in chars]
        caption = ax.set_title("", fontsize=9, animated=True)
        fig.canvas.draw()
        background = fig.canvas.copy_from_bbox(fig.bbox)
        note = f" [{plan.note}]" if plan.note else ""
        images, total, palette = [], len(plan.frames) + 1, None
        for k, f in enumerate(plan.frames):
            key = f in keys
            fig.canvas.restore_region(background)
            for (_, p, col), d, art in zip(chars, data, artists):
                bones = np.array(_bones(p)).reshape(-1, 2)
                color, width = (KEY_COLOR, 3.0) if key else (col, 2.0)
                if view == "3d":
                    for line, (a, b) in zip(art, bones):
                        line.set_data_3d(d[f, [a, b], 0], d[f, [a, b], 1], d[f, [a, b], 2])
                        line.set_color(color)
                        line.set_linewidth(width)
                        ax.draw_artist(line)
                else:
                    art.set_segments(_segments(d[f], p))
                    art.set_color(color)
                    art.set_linewidth(width)
                    ax.draw_artist(art)
            caption.set_text(f"frame {f + first_frame}" + (" (key)" if key else "") + note)
            ax.draw_artist(caption)
            rgb = canvas_rgb(fig)
            if palette is None:   # one palette for all frames, from the first (colours drawn later kept exactly)
                palette = GifPalette(rgb, ("#ffffff", KEY_COLOR, FLOOR_COLOR, OTHER_COLOR, OTHER_COLOR_B))
            images.append(palette.apply(rgb))
            if progress is not None:
                progress(k + 1, total)
    finally:
        plt.close(fig)
    write_gif(path, images, plan.durations_ms)
    if progress is not None:
        progress(total, total)
    return os.fspath(path)


# ------------------------------------------------------------------------------- BVH previews
def motion_positions(motion) -> np.ndarray:
    """(T, J, 3) global joint positions of a :class:`inbetween_jax.data.Motion` (forward kinematics)."""
    return np.asarray(motion.global_positions())


def preview_writers(positions, parents, name: str, *, fps: float = 30.0, every: int = 5,
                    keyframes: Sequence[int] = (), generated=None, gif: bool = False, stride: int = 1,
                    title: Optional[str] = None, first_frame: int = 0, positions_b=None, parents_b=None,
                    progress: Progress = None) -> dict:
    """Checked writers of a motion's previews, ``{file name: writer(path) -> path}``, to be called later
    (e.g. all into a temporary folder, so that a failure writes nothing).

    positions: (T, J, 3); keyframes / generated / every / first_frame as in :func:`contact_sheet`.
    One character: ``<name>_sheet.png`` (and ``<name>.gif`` with ``gif``, every ``stride``-th frame or
    sparser, see :func:`animate`).
    Two characters (positions_b (T, Jb, 3) on ``parents_b``, default ``parents``): one sheet per character,
    ``<name>_A_sheet.png`` and ``<name>_B_sheet.png``, ``<name>_pair_sheet.png`` with both in each pose slot
    (side view, placed relative to character A's root), and one GIF showing both.
    The inputs are checked here (ValueError with a one-line message). ``progress(done, total)`` is passed
    to each writer (it counts from 0 again for each file).
    """
    pos, par = _check_positions(positions, parents)
    t = pos.shape[0]
    chars = [("", pos, par)]
    if positions_b is not None:
        pos_b, par_b = _check_positions(positions_b, parents if parents_b is None else parents_b, "positions_b")
        if pos_b.shape[0] != t:
            raise ValueError(f"positions_b have {pos_b.shape[0]} frames but positions have {t}")
        chars = [("_A", pos, par), ("_B", pos_b, par_b)]
    if int(every) < 1 or int(stride) < 1 or not fps > 0:
        raise ValueError(f"every and stride must be >= 1 and fps > 0, got every={every}, stride={stride}, fps={fps}")
    keys = _check_keyframes(keyframes, t)
    gen = None if generated is None else _check_generated(generated, t)
    files = {}
    for suffix, p, pa in chars:
        label = f"{title}{' -- character ' + suffix[1] if suffix else ''}" if title else None
        files[f"{name}{suffix}_sheet.png"] = (
            lambda path, p=p, pa=pa, label=label: contact_sheet(p, pa, path, every=int(every), keyframes=keys,
                                                                title=label, generated=gen, first_frame=first_frame,
                                                                progress=progress))
    if len(chars) == 2:   # both characters in one picture: each pose slot holds the pair, placed as captured
        both = np.concatenate([pos, chars[1][1]], axis=1)
        par_b2 = np.asarray(chars[1][2])
        par_both = np.concatenate([np.asarray(par), np.where(par_b2 < 0, -1, par_b2 + len(par))])
        label = f"{title} -- both characters" if title else None
        files[f"{name}_pair_sheet.png"] = lambda path: contact_sheet(
            both, par_both, path, every=int(every), keyframes=keys, title=label, generated=gen,
            first_frame=first_frame, progress=progress)
    if gif:
        two = len(chars) == 2
        files[f"{name}.gif"] = lambda path: animate(
            pos, par, path, fps=fps, keyframes=keys, positions_b=chars[1][1] if two else None,
            parents_b=chars[1][2] if two else None, stride=int(stride), first_frame=first_frame,
            progress=progress)
    return files


def bvh_previews(motion, name: str, frames=(None, None), every: int = 5, keyframes: Sequence[int] = (),
                 gif: bool = False, *, progress: Progress = None) -> dict:
    """Checked writers (see :func:`preview_writers`) of the previews of frames [a, b) of a BVH motion.

    frames: (a, b), either may be None; negative numbers count from the end.  keyframes: frame numbers
    of the file (drawn black; they must lie in the selection); the sheet and the GIF print file frame
    numbers.  Writes ``<name>_sheet.png`` (and ``<name>.gif``); ``progress`` as in :func:`preview_writers`.
    Drawn in centimetres, whatever the file's unit (:func:`~inbetween_jax.data.features.detect_unit_scale`).
    """
    from inbetween_jax.data.features import detect_unit_scale
    n = motion.num_frames
    a, b = frames
    sel = range(n)[slice(a, b)]
    if len(sel) == 0:
        raise ValueError(f"{name}: frames {'' if a is None else a}:{'' if b is None else b} select none of "
                         f"its {n} frames")
    first = sel.start
    keys = [int(k) - first for k in keyframes]
    if any(not 0 <= k < len(sel) for k in keys):
        raise ValueError(f"{name}: keyframes {list(keyframes)} must lie in the selected frames "
                         f"[{first}, {first + len(sel)})")
    part = motion.slice(sel.start, sel.stop)
    cm = detect_unit_scale(motion.skeleton)                       # as infill's previews (cli/outputs.py)
    return preview_writers(motion_positions(part) * cm, part.skeleton.parents, name, fps=motion.fps, every=every,
                           keyframes=keys, gif=gif, title=name, first_frame=first,
                           progress=progress)
