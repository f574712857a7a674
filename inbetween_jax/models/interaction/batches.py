"""Training batches and evaluation windows of two-character motion (:class:`~inbetween_jax.models.interaction.
data.PairedMotion`), in the keypose spaces of :mod:`inbetween_jax.models.interaction.features`.

    sample_batch(pairs, rng, batch)                       random training windows, both characters mirrored together
    eval_windows(pairs, n_input, transition, stride)      every window of a split, deterministic
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from inbetween_jax.models.interaction.data import PairedMotion
from inbetween_jax.models.interaction.features import (keyframe_sample, mirror_feats, relative_space, root_space,
                                                       scale_positions, skeleton_side_axis, to_space)

__all__ = ["sample_batch", "eval_windows"]


def sample_batch(pairs: Sequence[PairedMotion], rng: np.random.Generator, batch: int, length: int = 50,
                 key_range=(50, 70), mirror: bool = True, pos_scale: float = 0.01) -> dict:
    """A random training batch (numpy float32): keys of :func:`keyframe_sample` with a leading batch axis;
    positions multiplied by ``pos_scale``.  Mirroring (p = 0.5) is applied to both characters together."""
    need = max(length, key_range[1] + 1)
    lens = np.array([max(p.num_frames - need, 0) for p in pairs], np.float64)
    if lens.sum() <= 0:
        raise ValueError(f"no pair has the {need} frames a sample needs")
    mm = pairs[0].skeleton.mirror_map()
    idx = rng.choice(len(pairs), size=batch, p=lens / lens.sum())
    starts = (rng.random(batch) * lens[idx]).astype(int)
    keys = rng.integers(key_range[0], key_range[1] + 1, size=batch)
    f = np.stack([pairs[i].feats[:, s:s + need] for i, s in zip(idx, starts)]).astype(np.float64)
    if mirror:
        flip = rng.random(batch) < 0.5
        f[flip] = mirror_feats(f[flip], mm, skeleton_side_axis(pairs[0].skeleton))
    kf = f[np.arange(batch), :, keys]                                       # (B, 2, J, 9)
    R, t = root_space(kf[:, :, 0], pairs[0].forward_axis)
    b = dict(x=to_space(f[:, :, :length], R[:, :, None], t[:, :, None]), keypose=to_space(kf, R, t))
    b["rel_R"], b["rel_t"] = relative_space(R, t, R[:, ::-1], t[:, ::-1])
    b["world_R"], b["world_t"] = R, t
    b = {k: v.astype(np.float32) for k, v in b.items()}
    return scale_positions(b, pos_scale)


def eval_windows(pairs: Sequence[PairedMotion], n_input: int, transition: int, stride: int,
                 pos_scale: float = 0.01, max_windows: Optional[int] = None) -> dict:
    """Deterministic test samples: ``n_input`` frames, ``transition`` frames to fill, the keyframe right after.

    Returns the :func:`keyframe_sample` keys with ``x`` (N, 2, n_input + transition + 1, J, 9) (last frame
    = keyframe) plus ``names``.  Empty dict if nothing fits.
    """
    length = n_input + transition + 1
    out, names = [], []
    for p in pairs:
        for s in range(0, p.num_frames - length + 1, stride):
            out.append(keyframe_sample(p.feats, s, length, length - 1, p.forward_axis))
            names.append(f"{p.name}@{s}")
    if max_windows is not None and len(out) > max_windows:
        sel = np.linspace(0, len(out) - 1, max_windows).round().astype(int)
        out, names = [out[i] for i in sel], [names[i] for i in sel]
    if not out:
        return {}
    b = {k: np.stack([o[k] for o in out]).astype(np.float32) for k in out[0]}
    b = scale_positions(b, pos_scale)
    b["names"] = names
    return b
