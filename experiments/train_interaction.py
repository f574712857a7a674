"""Train the two-character interaction in-betweening model.

``python experiments/train.py interaction [--source DIR] [--run-dir DIR] [--variant tiny] [key=value ...]``

Data: a folder of real paired BVH files (``<name>_A.bvh`` / ``<name>_B.bvh`` or ``pairs.txt``), else the
folder's single-person clips paired by construction (same LaFAN1 choreography, second performer placed
facing the first); default ``$LAFAN1_DIR`` or the embedded CMU clips.  Overrides are config keys
(``inbetween_jax/configs/interaction.py``), e.g. ``train.num_steps=2000 model.interaction=false``.
"""
from __future__ import annotations

import json
import os
import sys
import time


def parse_args(argv):
    """-> (source, run_dir, variant, overrides)."""
    opts = {"--source": None, "--run-dir": None, "--variant": "default"}
    overrides = []
    it = iter(argv)
    for a in it:
        if a in opts:
            opts[a] = next(it, None)
            if opts[a] is None:
                raise SystemExit(f"{a} needs a value")
        elif a.startswith("--"):
            raise SystemExit(f"unknown option {a}")
        else:
            overrides.append(a)
    source, run_dir, variant = opts["--source"], opts["--run-dir"], opts["--variant"]
    return source, run_dir or os.path.join("runs", "interaction"), variant, overrides


def main(argv: list[str]) -> int:
    from inbetween_jax.configs.interaction import get_config
    from inbetween_jax.models.interaction_data import load_pairs, split_pairs
    from inbetween_jax.models.interaction_train import make_training
    from inbetween_jax.train import apply_overrides, config_to_dict, run_training

    source, run_dir, variant, overrides = parse_args(argv)
    cfg = apply_overrides(get_config(variant), overrides)
    pairs = load_pairs(source, cfg.data.pair_distance)
    train = split_pairs(pairs, "train", cfg.data.split)
    J = train[0].feats.shape[2]
    os.makedirs(run_dir, exist_ok=True)
    meta = dict(source=source, variant=variant, overrides=overrides, config=config_to_dict(cfg),
                pairs=[dict(name=p.name, frames=p.num_frames, constructed=p.constructed) for p in pairs],
                train_frames=int(sum(p.num_frames for p in train)), num_joints=J,
                forward_axis=[float(v) for v in train[0].forward_axis])
    with open(os.path.join(run_dir, "interaction_meta.json"), "w") as f:
        json.dump(meta, f, indent=1)
    kind = "constructed" if any(p.constructed for p in pairs) else "real"
    print(f"{len(pairs)} {kind} pairs, {meta['train_frames']} training frames, {J} joints", flush=True)
    _, init_fn, step_fn, batch_fn = make_training(cfg, J, train[0].forward_axis, train)
    t0 = time.time()
    _, logged = run_training(init_fn, step_fn, batch_fn, cfg, run_dir, cfg.train.num_steps,
                             cfg.train.log_every, cfg.train.ckpt_every, cfg.train.seed)
    wall = time.time() - t0
    with open(os.path.join(run_dir, "wall_time.json"), "w") as f:
        json.dump(dict(seconds=wall, steps=cfg.train.num_steps), f)
    if logged:
        print(f"done in {wall:.0f} s; last: {logged[-1]}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    sys.exit(main(sys.argv[1:]))
