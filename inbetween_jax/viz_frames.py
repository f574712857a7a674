"""Which frames a preview draws, and how its files are written (helpers of :mod:`inbetween_jax.viz`).

A contact sheet draws at most ``MAX_POSES`` poses and a GIF has at most ``MAX_GIF_FRAMES`` frames, whatever
the length of the motion, so that a preview of a long file takes bounded time.  A GIF plays at most
``MAX_GIF_FPS`` frames per second (GIF delays are whole centiseconds and most viewers slow down delays
under 2 cs): the frame stride is an integer and the per-frame delays are rounded so that the GIF plays
as long as the motion lasts.
"""
from __future__ import annotations

import math
import os
import secrets
from typing import Callable, NamedTuple, Optional, Sequence

import numpy as np

MAX_POSES = 40          # poses on one contact sheet
MAX_GIF_FRAMES = 400    # frames in one GIF
MAX_GIF_FPS = 30.0      # frames per second a GIF plays at most
MIN_DELAY_MS = 20       # shortest GIF frame delay (most viewers slow down shorter ones)

Progress = Optional[Callable[[int, int], None]]


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


class SheetPlan(NamedTuple):
    """frames: sorted frame indices drawn; keyframes: those of them drawn as keyframes; step: the regular
    frame step used; note: a short sentence when fewer frames than requested are drawn, else ``""``."""
    frames: list
    keyframes: list
    step: int
    note: str


def sheet_frames(num_frames: int, every: int = 5, keyframes: Sequence[int] = (),
                 max_poses: int = MAX_POSES) -> SheetPlan:
    """Frames a contact sheet of ``num_frames`` frames draws: every ``every``-th frame and the keyframes,
    at most ``max_poses`` in all.

    When that is too many, the regular step grows (``ceil(num_frames / room)``, ``room`` being what the
    keyframes leave free) and, if the keyframes alone are too many, evenly spaced keyframes are kept.
    """
    t, every, max_poses = int(num_frames), int(every), int(max_poses)
    if t < 1 or every < 1 or max_poses < 2:
        raise ValueError(f"need num_frames >= 1, every >= 1 and max_poses >= 2, got {t}, {every}, {max_poses}")
    keys = sorted({int(k) for k in keyframes})
    notes = []
    if len(keys) > max_poses // 2 and len(set(range(0, t, every)) | set(keys)) > max_poses:
        kept = [keys[i] for i in np.unique(np.linspace(0, len(keys) - 1, max_poses // 2).round().astype(int))]
        notes.append(f"{len(kept)} of {len(keys)} keyframes")
        keys = kept
    step = every
    if len(set(range(0, t, step)) | set(keys)) > max_poses:
        step = max(every, -(-t // (max_poses - len(keys))))
        notes.insert(0, f"every {_ordinal(step)} of {t} frames")
    frames = sorted(set(range(0, t, step)) | set(keys))
    note = f"(showing {' and '.join(notes)})" if notes else ""
    return SheetPlan(frames, keys, step, note)


class GifPlan(NamedTuple):
    """frames: source frame indices shown (0, stride, 2*stride, ...); stride: the integer frame step;
    durations_ms: how long each frame is shown, multiples of 10 ms (GIF delays are centiseconds), at
    least ``MIN_DELAY_MS``, summing to the motion's duration (``num_frames / fps``) to within 10 ms
    (plus what the last frame's minimum delay adds); note: a short sentence when the requested stride
    was raised to bound the frame count, else ``""``."""
    frames: list
    stride: int
    durations_ms: list
    note: str


def gif_frames(num_frames: int, fps: float, stride: int = 1, *, max_fps: float = MAX_GIF_FPS,
               max_frames: int = MAX_GIF_FRAMES) -> GifPlan:
    """Frames of a GIF of ``num_frames`` frames sampled at ``fps``: the smallest stride that is at least
    ``stride``, plays at most ``max_fps`` (1 % tolerance, so 30.00001 Hz BVH files keep every frame) and
    gives at most ``max_frames`` frames."""
    t, stride, max_frames = int(num_frames), int(stride), int(max_frames)
    if t < 1 or stride < 1 or max_frames < 1 or not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"need num_frames >= 1, stride >= 1, max_frames >= 1 and fps > 0, got "
                         f"{t}, {stride}, {max_frames}, {fps}")
    if not 0 < max_fps <= 1000.0 / MIN_DELAY_MS:
        raise ValueError(f"max_fps must be in (0, {1000.0 / MIN_DELAY_MS:g}], got {max_fps}")
    by_rate = max(1, math.ceil(fps / max_fps - 0.01))
    by_count = -(-t // max_frames)
    s = max(stride, by_rate, by_count)
    frames = list(range(0, t, s))
    ends = [min(f + s, t) for f in frames]                               # each frame is held until the next
    cs = [round(e / fps * 100.0) for e in ends]                          # cumulative end times, centiseconds
    durations = [10 * max(b - a, MIN_DELAY_MS // 10) for a, b in zip([0] + cs[:-1], cs)]
    note = f"every {_ordinal(s)} frame" if by_count > max(stride, by_rate) else ""
    return GifPlan(frames, s, durations, note)


# ------------------------------------------------------------------------------------- writing
def save_atomic(path, save: Callable, suffix: str = "") -> str:
    """Call ``save(binary_file)`` on a new temporary file beside ``path``, then rename it to ``path``.

    The temporary file is made with mode 0644 (less the umask), like an ordinary file; on any error,
    KeyboardInterrupt included, it is removed and ``path`` is left as it was.  Returns ``path``.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    while True:
        tmp = os.path.join(directory, f".{os.path.basename(path)}.{secrets.token_hex(4)}.tmp{suffix}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o644)
            break
        except FileExistsError:
            continue
    try:
        with os.fdopen(fd, "wb") as fh:
            save(fh)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise
    return path


def write_gif(path, frames: Sequence, durations_ms: Sequence[int]) -> str:
    """Write PIL images ``frames`` as a looping GIF (``durations_ms[k]``: delay of frame k), atomically."""
    if not frames or len(frames) != len(durations_ms):
        raise ValueError(f"need one duration per frame, got {len(frames)} frames, {len(durations_ms)} durations")
    durations = [int(d) for d in durations_ms]
    return save_atomic(path, lambda fh: frames[0].save(fh, format="GIF", save_all=True,
                                                        append_images=list(frames[1:]), duration=durations,
                                                        loop=0), ".gif")


def canvas_rgb(fig):
    """What the figure's Agg canvas holds now (no redraw), as an RGB PIL image."""
    from PIL import Image
    return Image.fromarray(np.ascontiguousarray(np.asarray(fig.canvas.buffer_rgba())[..., :3]))


class GifPalette:
    """One palette for all frames of a GIF: the ``exact`` colours ("#rrggbb", kept exactly) and a median cut of
    RGB PIL ``image`` (say the first frame).  :meth:`apply` maps a frame's pixels to their nearest palette
    colour, remembering each colour's entry (a 2**24 table), so that each frame costs a table look-up
    rather than a fresh quantization."""

    def __init__(self, image, exact: Sequence[str] = ()):
        from PIL import Image
        extra = [tuple(int(c[i:i + 2], 16) for i in (1, 3, 5)) for c in exact]
        cut = image.quantize(colors=256 - len(extra), method=Image.Quantize.MEDIANCUT)
        rgb = cut.getpalette()
        colours = [tuple(rgb[3 * i:3 * i + 3]) for i in sorted(i for _, i in cut.getcolors(256))]
        colours = list(dict.fromkeys(extra + colours))[:256]
        self.colours = np.array(colours + [colours[0]] * (256 - len(colours)), np.int32)   # (256, 3)
        self._entry = np.full(1 << 24, -1, np.int16)                                      # packed RGB -> entry

    def apply(self, image):
        """RGB PIL image -> palette ("P") PIL image on this palette."""
        from PIL import Image
        rgb = np.asarray(image, dtype=np.uint8).astype(np.int32)
        packed = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]                      # (H, W)
        index = self._entry[packed]
        if (index < 0).any():
            new = np.unique(packed[index < 0])
            new_rgb = np.stack([new >> 16, (new >> 8) & 255, new & 255], -1)               # (U, 3)
            dist = ((new_rgb[:, None, :] - self.colours[None]) ** 2).sum(-1)               # (U, 256)
            self._entry[new] = dist.argmin(1)
            index = self._entry[packed]
        out = Image.fromarray(index.astype(np.uint8), mode="P")
        out.putpalette(self.colours.astype(np.uint8).ravel().tolist())
        return out
