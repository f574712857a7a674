"""Write the 31-joint CMU files of ``cmu_more/mb31`` (or the ASF-named ones of ``cmu_bvh``: 16_01, 16_02, 18_01) as
BVH files on the 43-joint body of ``cmu_bvh`` / ``daz43`` (:func:`inbetween_jax.data.rig_transfer.transfer_rig`;
the ``cmu`` source does the same in memory).

    python experiments/retarget_mb31.py ../shared/data/cmu_more/mb31 OUT_DIR [--template FILE.bvh] [--only A.bvh,B.bvh]

One BVH per input, same name, on the template's skeleton at the input's frame rate.
"""
from __future__ import annotations

import argparse
import os
import sys


def main(argv=None) -> int:
    from inbetween_jax.data import read_bvh
    from inbetween_jax.data.bvh import write_bvh
    from inbetween_jax.data.rig_transfer import transfer_rig
    from inbetween_jax.paths import shared_data_dir
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("src")
    ap.add_argument("out")
    ap.add_argument("--template", default=None, help="a BVH on the target body (default: cmu_bvh/02_01.bvh)")
    ap.add_argument("--only", default=None, help="comma-separated file names (default: every BVH in SRC)")
    a = ap.parse_args(argv)
    template = read_bvh(a.template or os.path.join(shared_data_dir(required=True), "cmu_bvh", "02_01.bvh"), 0, 2)
    os.makedirs(a.out, exist_ok=True)
    wanted = set(a.only.split(",")) if a.only else None
    for name in sorted(n for n in os.listdir(a.src) if n.lower().endswith(".bvh") and (not wanted or n in wanted)):
        m = transfer_rig(read_bvh(os.path.join(a.src, name)), template)
        write_bvh(os.path.join(a.out, name), m)
        print(f"{name}: {m.num_frames} frames", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
