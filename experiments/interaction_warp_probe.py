"""The interaction model's sampled mode with bank windows warped by local-support offsets; not in the package
(docs/results/interaction.md, "Why the samples' score stays low").

    python experiments/interaction_warp_probe.py RUN_DIR [--support M | --pair M] [--match-velocity M]
        [--foot-clock feet|legs] [interaction_samples.py options]

The sampled mode blends each sample with one captured bank window warped onto the query's ends
(``bank._warped_mean``): every joint channel gets the start offset fading linearly into the end offset over the
whole gap (Witkin & Popovic 1995), so the captured pose changes everywhere by the two keyposes' difference.  With
``--support M`` > 0 this script swaps that warp, for its own process, for a local-support one: the root moves
rigidly along the same linear offset, and the other joints' offsets relative to the root (and the rotation
channels' offsets) fade in and out within M frames of either end (raised cosine), so the captured window's own poses
are kept between.  ``--support 0`` is the package's warp.  With ``--match-velocity M`` > 0 each warped window also
gets the context's last velocity at its first frame: the difference, times the frame number, fading out within M
frames (raised cosine).  ``--pair M`` > 0: both dancers move by one shared rigid offset (the mean of their roots'),
so the captured pair keeps its relative placement, each joint's own offset fading within M frames of the ends.
``--foot-clock feet`` (``legs``: with the shins) moves each foot's share of the offset as the captured foot travels,
not linearly in time, so a planted foot does not slide (:func:`foot_clock`).  Then it runs ``experiments/interaction_samples.py``
with the other arguments: the samples table on the validation take (classifier on the ``fit`` takes).
"""
import argparse
import os
import runpy
import sys

import numpy as np

from inbetween_jax.models.interaction import bank


def raised_cosine(gap: int, m: int) -> tuple:
    """(gap,) weights of the start and end offsets: 1 at the keyframe side, 0 from ``m`` frames away."""
    f = np.arange(1, gap + 1, dtype=np.float32)
    start = np.where(f < m, 0.5 * (1 + np.cos(np.pi * f / m)), 0.0)
    end = np.where(gap + 1 - f < m, 0.5 * (1 + np.cos(np.pi * (gap + 1 - f) / m)), 0.0)
    return start.astype(np.float32), end.astype(np.float32)


def local_warped_mean(m: int, shared: bool = False):
    """Each dancer moves rigidly along its root's linear offset (``shared``: both dancers along the mean of their
    roots', so the captured pair keeps its relative placement); each joint's offset from that, and the rotation
    channels' offsets, fade in and out within ``m`` frames of either end."""
    def warped_mean(near, context, keypose, gap: int) -> np.ndarray:
        """near (B, k, 2, n + gap + 1, J, 9) -> (B, 2, gap, J, 9): the mean of the k windows, each warped."""
        n = context.shape[2]
        t = np.arange(1, gap + 1, dtype=np.float32) / (gap + 1)
        ws, we = raised_cosine(gap, m)
        sh = lambda v: v[None, None, :, None, None]                                  # noqa: E731
        out = np.zeros(context.shape[:2] + (gap,) + context.shape[3:], np.float32)
        for j in range(near.shape[1]):
            c = near[:, j]
            start = (context[:, :, -1] - c[:, :, n - 1])[:, :, None]                   # (B, 2, 1, J, 9)
            end = (keypose - c[:, :, -1])[:, :, None]
            s0, e0 = start[..., :1, :3], end[..., :1, :3]                              # the roots' offsets
            if shared:
                s0, e0 = s0.mean(1, keepdims=True), e0.mean(1, keepdims=True)
            off = np.zeros(c.shape[:2] + (gap,) + c.shape[3:], np.float32)
            off[..., :3] = ((1 - sh(t)) * s0 + sh(t) * e0 + sh(ws) * (start[..., :3] - s0)
                            + sh(we) * (end[..., :3] - e0))
            off[..., 3:] = sh(ws) * start[..., 3:] + sh(we) * end[..., 3:]
            out += c[:, :, n:n + gap] + off
        return out / near.shape[1]
    return warped_mean


def velocity_matched(warp, m: int):
    """``warp`` plus a correction that gives each warped window the context's last velocity at the start:
    ``delta * f * cos^2``-fade over ``m`` frames, delta = context velocity - the warped window's first step."""
    def warped_mean(near, context, keypose, gap: int) -> np.ndarray:
        k = raised_cosine(gap, m)[0] * np.arange(1, gap + 1, dtype=np.float32)
        v_ctx = context[:, :, -1] - context[:, :, -2]                                  # (B, 2, J, 9)
        out = 0.0
        for j in range(near.shape[1]):
            one = warp(near[:, j:j + 1], context, keypose, gap)
            delta = v_ctx - (one[:, :, 0] - context[:, :, -1])
            out = out + one + delta[:, :, None] * k[None, None, :, None, None]
        return out / near.shape[1]
    return warped_mean


def foot_clock(warp, chains):
    """``warp`` with the offsets of the joints in ``chains`` ((foot, [joints that follow it]), ...) re-timed: their
    share of the start-to-end offset grows with the foot's own horizontal travel in the captured window instead of
    linearly in time, so a planted foot stays planted (the linear warp slides the whole body over the floor).  A
    foot that travels less than 1 cm over the gap keeps the linear clock."""
    def warped_mean(near, context, keypose, gap: int) -> np.ndarray:
        n = context.shape[2]
        t = np.arange(1, gap + 1, dtype=np.float32) / (gap + 1)
        out = 0.0
        for j in range(near.shape[1]):
            c = near[:, j]
            one = warp(near[:, j:j + 1], context, keypose, gap)                        # (B, 2, gap, J, 9)
            start = (context[:, :, -1] - c[:, :, n - 1])[..., :3]                      # (B, 2, J, 3)
            end = (keypose - c[:, :, -1])[..., :3]
            for foot, joints in chains:
                path = c[:, :, n - 1:, foot, :3][..., [0, 2]]                           # (B, 2, gap + 2, 2)
                step = np.linalg.norm(np.diff(path, axis=2), axis=-1)                  # (B, 2, gap + 1)
                total = step.sum(-1, keepdims=True)
                tau = np.where(total > 0.01, np.cumsum(step, -1)[..., :gap] / np.maximum(total, 1e-9), t)
                for q in joints:   # swap the linear share of the offset for the foot's clock
                    one[..., q, :3] += ((tau - t)[..., None] * (end[:, :, None, q] - start[:, :, None, q]))
            out = out + one
        return out / near.shape[1]
    return warped_mean


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], add_help=False)
    warp = p.add_mutually_exclusive_group()
    warp.add_argument("--support", type=int, default=0, metavar="M")
    warp.add_argument("--pair", type=int, default=0, metavar="M")
    p.add_argument("--match-velocity", type=int, default=0, metavar="M")
    p.add_argument("--foot-clock", choices=("feet", "legs"), default=None)
    a, rest = p.parse_known_args()
    if a.support > 0:
        bank._warped_mean = local_warped_mean(a.support)        # this process only: the probe's variant
    if a.pair > 0:
        bank._warped_mean = local_warped_mean(a.pair, shared=True)
    if a.match_velocity > 0:
        bank._warped_mean = velocity_matched(bank._warped_mean, a.match_velocity)
    if a.foot_clock:
        from inbetween_jax.models.interaction.infer import load
        from inbetween_jax.train.run import load_run
        names = list(load(load_run(rest[0])).skeleton.names)
        chains = [(names.index(f"{s}Foot"), [names.index(f"{s}Foot")] + ([names.index(f"{s}Shin")]
                   if a.foot_clock == "legs" else [])) for s in "rl"]
        bank._warped_mean = foot_clock(bank._warped_mean, chains)
    sys.argv = ["interaction_samples.py"] + rest
    runpy.run_path(os.path.join(os.path.dirname(__file__), "interaction_samples.py"), run_name="__main__")


if __name__ == "__main__":
    main()
