"""Choose the interaction model's ``model.ease_frames`` on the validation take: L2P at 30 / 50 frames (true gap,
one sample; bench.val_score's windows) and the snap onto the keypose (last generated step over the median step
of the fill, per window; mean and 90th percentile) for each value.

    python experiments/interaction_ease.py [--run WEIGHTS_OR_RUN_DIR] [--source ../shared/data/cmu_pairs] [--test]
"""
import argparse
import dataclasses

import jax
import numpy as np

from inbetween_jax.models.interaction import bench
from inbetween_jax.models.interaction.infer import load
from inbetween_jax.shipped import shipped_dir
from inbetween_jax.train.run import load_run

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--run", default=None)
p.add_argument("--source", default="../shared/data/cmu_pairs")
p.add_argument("--values", default="0,5,10,15")
p.add_argument("--test", action="store_true", help="the test takes instead of the validation take (look once)")
a = p.parse_args()
trained = load(load_run(a.run or shipped_dir("interaction")))
d = trained.cfg.data
windows, stats = bench._val_data(a.source, d.pair_distance, tuple(d.split), d.pos_scale, 64)
if a.test:
    from inbetween_jax.evaluation.interaction import table1_windows
    from inbetween_jax.models.interaction.data import load_pairs, split_pairs
    windows = table1_windows(split_pairs(load_pairs(a.source, d.pair_distance), "test", tuple(d.split)), d.pos_scale,
                             64, bench.VAL_LENGTHS)
for ease in [int(v) for v in a.values.split(",")]:
    t = dataclasses.replace(trained, cfg=dataclasses.replace(trained.cfg, model=dataclasses.replace(
        trained.cfg.model, ease_frames=ease)))
    method = bench._model_method(t)
    l2p = bench.windows_l2p(method, windows, stats, d.n_pred)
    snaps = []
    for L in bench.VAL_LENGTHS:
        w = windows[L]
        out = np.asarray(method(w, -(-L // d.n_pred), 1, jax.random.key(L)))[0, :, :, :L, :, :3]   # (B, 2, L, J, 3)
        path = np.concatenate([out, np.asarray(w["keypose"])[:, :, None, :, :3]], 2)
        step = np.linalg.norm(np.diff(path, axis=2), axis=-1).mean(-1)                        # (B, 2, L)
        snaps.append(step[..., -1] / np.median(step[..., :-1], axis=-1))
    s = np.concatenate(snaps).ravel()
    print(f"ease {ease:2d}: val L2P {' / '.join(f'{x:.4f}' for x in l2p)} (mean {np.mean(l2p):.4f}); last step / "
          f"median step: mean {s.mean():.2f}, p90 {np.quantile(s, 0.9):.2f}, max {s.max():.2f}")
