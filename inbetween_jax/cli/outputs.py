"""Writing command outputs: all files into a temporary folder first, then moved into ``--out`` together.

Folders get mode 0777 and files 0666 minus the umask (0755 / 0644 usually), like any program's outputs.
"""
from __future__ import annotations

import os
import shutil

from inbetween_jax.cli import interrupt

__all__ = ["check_out", "write_outputs", "bvh_writer", "npy_writer", "json_writer", "add_previews"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_out(out_arg: str, overwrite: bool) -> None:
    """``--out`` must be a folder (or not exist yet) and be empty unless ``overwrite``."""
    from inbetween_jax.errors import UserError
    out = os.path.abspath(out_arg)
    if os.path.exists(out) and not os.path.isdir(out):
        raise UserError(f"--out {out_arg}: exists and is not a folder")
    if os.path.isdir(out) and os.listdir(out) and not overwrite:
        raise UserError(f"--out {out_arg}: folder is not empty (choose a new folder or pass --overwrite)")


def write_outputs(out: str, files: dict, progress=None) -> None:
    """Write ``{name: writer(path)}`` into a temporary folder (a sibling of ``out``, or inside ``out`` when it
    exists), then move them into ``out``; on any error or interrupt nothing reaches ``out``."""
    out = os.path.abspath(out)
    parent = out if os.path.isdir(out) else os.path.dirname(out)
    os.makedirs(parent, exist_ok=True)
    tmp = interrupt.temp_dir(f".{os.path.basename(out)}.tmp-", parent)
    mask = _umask()
    try:
        for i, (name, writer) in enumerate(files.items()):
            path = os.path.join(tmp, name)
            writer(path)
            os.chmod(path, 0o666 & ~mask)
            if progress:
                progress(i + 1, len(files), name)
        os.chmod(tmp, 0o777 & ~mask)
        with interrupt.critical():
            if not os.path.exists(out):
                os.rename(tmp, out)
                return
            for name in files:
                os.replace(os.path.join(tmp, name), os.path.join(out, name))
    finally:
        if os.path.isdir(tmp):
            shutil.rmtree(tmp, ignore_errors=True)
        interrupt.untrack(tmp)


def bvh_writer(motion):
    from inbetween_jax.data import write_bvh
    return lambda path: write_bvh(path, motion)


def npy_writer(array):
    def write(path):
        import numpy as np
        with open(path, "wb") as f:          # np.save(path) would append .npy to the temporary name
            np.save(f, array)
    return write


def json_writer(obj):
    def write(path):
        import json
        with open(path, "w") as f:
            json.dump(obj, f, indent=1)
    return write


def add_samples_sheet(files: dict, motions: list, what: str = "keyframes", name: str = "samples_sheet",
                      who: str = "") -> None:
    """Add ``name.png``: every sample of one in-between overlaid frame by frame, one colour each
    (:func:`inbetween_jax.viz_samples.samples_sheet`).  motions: one Motion per sample, the same frames; who: the
    character's name for the title (two-character in-betweens get one sheet per character)."""
    import numpy as np

    from inbetween_jax.data.features import detect_unit_scale
    from inbetween_jax.viz import motion_positions
    from inbetween_jax.viz_samples import MAX_SAMPLES_DRAWN, samples_sheet
    motions = motions[:MAX_SAMPLES_DRAWN]
    cm = detect_unit_scale(motions[0].skeleton)
    pos = np.stack([motion_positions(m) * cm for m in motions])
    t = pos.shape[1]
    every = max(1, -(-t // 12))
    title = f"{who + ': ' if who else ''}{len(motions)} samples overlaid (one colour each), {what} black"
    files[f"{name}.png"] = lambda path: samples_sheet(pos, motions[0].skeleton.parents, path, every=every,
                                                      keyframes=[0, t - 1], title=title)


def add_previews(files: dict, name: str, motions: list, generated=None, what: str = "keyframes",
                 gif: bool = False) -> None:
    """Add ``name``'s contact sheet (and with ``gif`` an animation) writers to ``files``.

    motions: [Motion] or [Motion A, Motion B] of T frames each; generated: (T,) bool, the frames drawn grey
    (default: all but the first and last).  The other frames are drawn black where the sheet shows them
    (every ``ceil(T / 16)``-th frame) and next to generated frames.
    """
    import numpy as np

    from inbetween_jax.data.features import detect_unit_scale
    from inbetween_jax.viz import motion_positions, preview_writers
    cm = detect_unit_scale(motions[0].skeleton)           # the drawings are laid out in centimetres
    pos = [motion_positions(m) * cm for m in motions]
    t = len(pos[0])
    every = max(1, -(-t // 16))
    gen = np.arange(t) % max(t - 1, 1) != 0 if generated is None else np.asarray(generated, bool)
    near = gen.copy()                                                        # generated or next to one
    near[1:] |= gen[:-1]
    near[:-1] |= gen[1:]
    keys = np.flatnonzero(~gen & ((np.arange(t) % every == 0) | near))
    files.update(preview_writers(
        pos[0], motions[0].skeleton.parents, name, fps=motions[0].fps, every=every,
        keyframes=keys, generated=gen, gif=gif, stride=max(1, -(-t // 300)),
        title=f"{name}: {what} black, generated grey", positions_b=pos[1] if len(pos) > 1 else None,
        parents_b=motions[-1].skeleton.parents))
