"""Train the convolutional inpainting AE: ``make train MODEL=cae ARGS='...'``.

``python experiments/train.py cae [--source DIR] [--run-dir DIR] [--preset paper|cpu|tiny] [key=value ...]``

Overrides are fields of ``inbetween_jax/configs/cae.py`` (``model.variant=vanilla``, ``batch_size=16``,
``mask.curriculum=false`` ...).  Re-running with the same ``--run-dir`` resumes from its latest checkpoint.
Default run folder: ``runs/cae/<variant>`` (``make bench`` evaluates every variant found in ``runs/cae``).
"""
from __future__ import annotations

import json
import os
import sys


def main(argv: list[str]) -> int:
    from inbetween_jax.configs.cae import get_config
    from inbetween_jax.models.cae_train import train
    from inbetween_jax.train import apply_overrides

    source = run_dir = None
    preset = "paper"
    overrides = []
    it = iter(argv)
    for a in it:
        if a in ("-h", "--help"):
            print(__doc__.strip())
            return 0
        if a.startswith("--source"):
            source = a.split("=", 1)[1] if "=" in a else next(it)
        elif a.startswith("--run-dir"):
            run_dir = a.split("=", 1)[1] if "=" in a else next(it)
        elif a.startswith("--preset"):
            preset = a.split("=", 1)[1] if "=" in a else next(it)
        else:
            overrides.append(a)
    cfg = apply_overrides(get_config(preset), overrides)   # fail early on a bad override
    run_dir = run_dir or os.path.join("runs", "cae", cfg.model.variant)
    _, logged, info = train(run_dir, source, preset, overrides)
    last = logged[-1] if logged else {}
    print(json.dumps({"run_dir": run_dir, **info, "last": last}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
