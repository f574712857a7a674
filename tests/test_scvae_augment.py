"""S-CVAE training-data switches judged on the validation subjects (docs/results/gate.md): ``data.tempo``
(the same files played faster / slower) and ``data.balance`` (windows drawn per activity group)."""
import numpy as np
import pytest

from inbetween_jax.data import load_dataset, load_motions
from inbetween_jax.data.activities import activity_group
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.train import apply_overrides


def test_tempo_copies_play_the_same_files_faster_and_slower():
    base = load_dataset(None, "train")
    both = T._with_tempo_copies(base, "embedded", "train", (2.0, 0.5))
    fast = load_dataset(None, "train", window=base.window, fps=base.fps / 2.0)
    assert both.window == base.window and both.fps == base.fps
    assert len(both) == len(base) + len(fast) + len(load_dataset(None, "train", window=base.window,
                                                                  fps=base.fps * 2.0))
    np.testing.assert_array_equal(both.root_pos[len(base):len(base) + len(fast)], fast.root_pos)
    travel = lambda ms: sum(np.linalg.norm(np.diff(m.root_pos, axis=0), axis=-1).sum() for m in ms)
    frames = lambda ms: sum(len(m.root_pos) for m in ms)
    one, two = load_motions(None, "train"), load_motions(None, "train", fps=base.fps / 2.0)
    # the same path in half the frames: root travel per frame doubles (a little less: chords of a curved path)
    assert 1.85 < (travel(two) / frames(two)) / (travel(one) / frames(one)) < 2.05
    np.testing.assert_array_equal(both.root_pos[:len(base)], base.root_pos)
    with pytest.raises(ValueError, match="data.tempo"):
        T._with_tempo_copies(base, "embedded", "train", (0.0,))


def test_balance_weights_give_every_activity_group_its_share():
    names = ["02_01@0"] * 6 + ["13_01@0"] * 2 + ["61_01@0"]     # walk, everyday, dance: 6, 2, 1 windows
    groups = [activity_group(n.split("@")[0]) for n in names]
    assert len(set(groups)) == 3
    for balance, expect in ((1.0, [1 / 3] * 3), (0.0, [6 / 9, 2 / 9, 1 / 9])):
        p = T.group_weights(names, balance)
        share = [p[[g == x for g in groups]].sum() for x in dict.fromkeys(groups)]
        np.testing.assert_allclose(share, expect, rtol=1e-12)
    cfg = apply_overrides(get_config("tiny"), ["data.balance=1.0", "data.trans_start=10", "data.trans_max=10"])
    data = T.load_data(cfg, "embedded", "train")
    batch = T.batch_fn_factory(data, cfg)(0, __import__("jax").random.key(0))
    assert batch["q"].shape[0] == cfg.train.batch_size
