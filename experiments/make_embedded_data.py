"""Build the embedded default data set shipped in ``inbetween_jax/assets/cmu30/``.

Source: CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu; free for all uses), the 43-joint
120 Hz BVH conversions in ``../shared/data/cmu_bvh``. Each file is downsampled to 30 Hz (every 4th
frame) and reduced to a 21-joint body skeleton (eyes and finger joints dropped; they are leaves, so
no other joint moves). Run once by the maintainers; the result is committed.

    python experiments/make_embedded_data.py --src ../shared/data/cmu_bvh --out inbetween_jax/assets/cmu30
"""
import argparse
import glob
import os

import numpy as np

from inbetween_jax.data.bvh import Motion, read_bvh, write_bvh
from inbetween_jax.data.skeleton import Skeleton

DROP = ("Eye", "Thumb", "Index", "Mid", "Ring", "Pinky")


def reduce_skeleton(m: Motion) -> Motion:
    skel = m.skeleton
    keep = [i for i, n in enumerate(skel.names) if not any(d in n for d in DROP)]
    remap = {old: new for new, old in enumerate(keep)}
    parents = tuple(-1 if skel.parents[i] < 0 else remap[skel.parents[i]] for i in keep)
    ends = [(remap[p], o) for p, o in skel.end_sites if p in remap]
    for i in keep:  # a joint whose children were all dropped gets an End Site at its first child
        kids = skel.children(i)
        if kids and not any(k in remap for k in kids) and not any(p == remap[i] for p, _ in ends):
            ends.append((remap[i], skel.offsets[kids[0]]))
    new = Skeleton(tuple(skel.names[i] for i in keep), parents, skel.offsets[keep],
                   tuple(skel.channels[i] for i in keep), tuple(ends))
    return Motion(new, m.local_quats[:, keep], m.local_pos[:, keep], m.frame_time, m.source)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--src", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--step", type=int, default=4)
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    total = 0
    for path in sorted(glob.glob(os.path.join(args.src, "*.bvh"))):
        m = read_bvh(path)
        if m.skeleton.num_joints != 43 or abs(m.frame_time - 1 / 120) > 1e-4:
            print(f"skip {os.path.basename(path)} ({m.skeleton.num_joints} joints, {m.fps:.0f} Hz)")
            continue
        m = reduce_skeleton(m).slice(0, None, args.step)
        write_bvh(os.path.join(args.out, os.path.basename(path)), m, decimals=4)
        total += m.num_frames
    print(f"wrote {total} frames at 30 Hz")


if __name__ == "__main__":
    np.seterr(all="raise")
    main()
