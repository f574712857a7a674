"""The S-CVAE ablation sweep: seeds vmapped in one program reproduce their single runs; ``inbetween sweep`` writes
a mean ± std table.  Real CMU windows (the embedded training split)."""
import json
import os

import jax
import numpy as np
import pytest

from inbetween_jax.cli import main
from inbetween_jax.data import load_dataset
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.features import TrainData, compute_stats
from inbetween_jax.train import enable_compilation_cache
from inbetween_jax.train import sweep

FRAMES = 10   # the tiny preset's own transition length: the sweep's "full" row is get_config("tiny")


def test_row_configs_turn_off_one_switch():
    from inbetween_jax.models.scvae.config import get_config
    full = sweep.row_config("tiny", "full", FRAMES)
    assert full == get_config("tiny")
    for row, (_, switch) in sweep.ABLATIONS["scvae"].items():
        m = sweep.row_config("tiny", row, FRAMES).model
        off = [f for f in ("bidirectional", "latent_interp", "aligning", "phase_moe", "encoder_lstm",
                           "discriminators", "stitch_loss") if not getattr(m, f)]
        assert off == ([] if switch is None else [switch])
    with pytest.raises(ValueError, match="unknown row"):
        sweep.row_config("tiny", "no_such_row", FRAMES)


def test_vmapped_seeds_match_single_seed_runs():
    enable_compilation_cache()
    cfg, seeds, steps = sweep.row_config("tiny", "full", FRAMES), [0, 1], 3
    windows = load_dataset(None, "train")
    stats = compute_stats(windows)
    data = TrainData.from_windows(windows, stats=stats)
    states, history, _ = sweep.train_seeds(T.make_training(cfg, data), seeds, steps)
    assert jax.tree.leaves(states["params"])[0].shape[0] == len(seeds)

    init_fn = jax.jit(T.make_init_fn(cfg, stats, data.q.shape[2]))
    step_fn = jax.jit(T.make_train_step(cfg, data.parents, cfg.data.trans_max + 1))   # one compile, both seeds
    batch_fn = T.batch_fn_factory(data, cfg)
    losses = []
    for n, seed in enumerate(seeds):   # the run_training recipe, one seed at a time, plain jitted step
        init_key, data_key, train_key = jax.random.split(jax.random.key(seed), 3)
        state = init_fn(init_key)
        for i in range(steps):
            batch = batch_fn(i, jax.random.fold_in(data_key, i))
            state, m = step_fn(state, batch, jax.random.fold_in(train_key, i))
            np.testing.assert_allclose(history[i]["loss"][n], m["loss"], rtol=1e-4, atol=1e-5)
            losses.append(float(m["loss"]))
        for (path, a), b in zip(jax.tree_util.tree_leaves_with_path(states["params"]),
                                jax.tree.leaves(state["params"])):
            np.testing.assert_allclose(np.asarray(a[n]), np.asarray(b), rtol=1e-4, atol=1e-5,
                                       err_msg=f"seed {seed} {jax.tree_util.keystr(path)}")
    assert losses[:steps] != losses[steps:], "two seeds gave the same run"


def test_sweep_cli_writes_mean_std_table(tmp_path):
    rows = ["full", "no_d"]
    assert main(["sweep", "--rows", ",".join(rows), "--seeds", "2", "--steps", "2", "--frames", str(FRAMES),
                       "--samples", "2", "--results", str(tmp_path)]) == 0
    md = (tmp_path / "sweep_scvae.md").read_text()
    lines = {line.split("|")[1].strip(): line for line in md.splitlines() if line.startswith("| ")}
    for row in rows:
        assert row in lines and lines[row].count("±") == len(sweep.COLUMNS) + 1, lines.get(row)
    assert "Slerp" in md
    with open(tmp_path / "sweep_scvae.json") as f:
        res = json.load(f)
    assert res["model"] == "scvae"
    assert [r["row"] for r in res["rows"]] == rows
    for r in res["rows"]:
        assert len(r["per_seed"]) == 2 and all(np.isfinite(m["L2P"]) for m in r["per_seed"])


def test_sweep_cli_refuses_an_unknown_row_in_one_line(tmp_path, capsys):
    assert main(["sweep", "--rows", "full,no_such_row", "--results", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no_such_row" in err
    assert not os.listdir(tmp_path)
