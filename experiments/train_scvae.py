"""Train the S-CVAE: ``python experiments/train_scvae.py [--source DIR] [--run-dir DIR] [--variant V] key=value ...``

``--variant`` picks the base config (paper | cpu | tiny, see ``inbetween_jax/configs/scvae.py``); every
``key=value`` overrides it (e.g. ``train.num_steps=2000 model.buffer_k=3``).  ``--source`` defaults to
``$LAFAN1_DIR`` or the embedded CMU set.  Re-running with the same ``--run-dir`` resumes from its latest
checkpoint.  Logs: ``<run-dir>/metrics.csv`` and ``metrics.jsonl``; checkpoints: ``<run-dir>/checkpoints``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main(argv: list[str]) -> int:
    from inbetween_jax.configs.scvae import get_config
    from inbetween_jax.data import load_dataset, resolve_source
    from inbetween_jax.models import scvae_train
    from inbetween_jax.train import apply_overrides, config_to_dict

    ap = argparse.ArgumentParser(prog="train_scvae", description=__doc__.split("\n")[0])
    ap.add_argument("--source", default=None, help="LaFAN1 / BVH folder or 'embedded' (default: $LAFAN1_DIR)")
    ap.add_argument("--run-dir", default=os.path.join("runs", "scvae"))
    ap.add_argument("--variant", default="paper", choices=("paper", "cpu", "tiny"))
    ap.add_argument("overrides", nargs="*", help="config overrides key=value")
    args = ap.parse_args(argv)
    cfg = apply_overrides(get_config(args.variant), args.overrides)
    source = resolve_source(args.source)
    windows = load_dataset(source, "train")
    os.makedirs(args.run_dir, exist_ok=True)
    meta_path = os.path.join(args.run_dir, "run.json")
    if os.path.exists(meta_path):   # resuming: refuse a run folder holding another configuration
        with open(meta_path) as f:
            old = json.load(f)
        if _core(old.get("config")) != _core(config_to_dict(cfg)) or old.get("source") != source:
            raise ValueError(f"{args.run_dir} holds a run with another config or source "
                             f"({old.get('variant')}, {old.get('overrides')}, {old.get('source')}); "
                             "pass the same settings to resume or choose another --run-dir")
    meta = {"source": source, "variant": args.variant, "overrides": args.overrides,
            "num_windows": len(windows), "num_joints": int(windows.local_quats.shape[2]),
            "config": config_to_dict(cfg)}
    with open(meta_path, "w") as f:
        json.dump(meta, f, indent=1)
    print(f"S-CVAE: {len(windows)} training windows from {source}, {cfg.train.num_steps} steps -> {args.run_dir}")
    t0 = time.time()
    _, logged = scvae_train.train(cfg, windows, args.run_dir)
    wall = time.time() - t0
    with open(os.path.join(args.run_dir, "wall_time.txt"), "a") as f:
        f.write(f"{wall:.1f}\n")
    print(f"done in {wall:.0f} s; last logged: {logged[-1] if logged else None}")
    return 0


def _core(config) -> dict:
    """The part of a config that must match to resume (run length and logging may change)."""
    c = json.loads(json.dumps(config or {}))
    for k in ("num_steps", "log_every", "ckpt_every"):
        c.get("train", {}).pop(k, None)
    return c


if __name__ == "__main__":
    main(sys.argv[1:])
