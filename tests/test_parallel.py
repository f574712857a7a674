"""Data-parallel training (``run_training(..., mesh=...)``) on two faked CPU devices reproduces the
single-device run of the S-CVAE on real CMU windows.

The device count is fixed when JAX starts, so the training runs in a subprocess started with
``XLA_FLAGS=--xla_force_host_platform_device_count=2``; it writes losses, parameters and sharding facts
to an npz / JSON that this process checks.  The mesh run is interrupted after a checkpoint and resumed.
"""
import json
import os
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STEPS = 3

CHILD = r"""
import json, sys
import jax, numpy as np
from inbetween_jax.data import load_dataset
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.models.scvae.features import TrainData, compute_stats
from inbetween_jax.train import apply_overrides, make_mesh, run_training, shard_batch

out, steps = sys.argv[1], int(sys.argv[2])
cfg = apply_overrides(get_config("tiny"), ["train.batch_size=4"])
windows = load_dataset(None, "train")
data = TrainData.from_windows(windows)
init_fn = jax.jit(T.make_init_fn(cfg, compute_stats(windows), data.q.shape[2]))  # compiled once, used twice
step_fn = T.make_train_step(cfg, data.parents, cfg.data.trans_max + 1)
batch_fn = T.batch_fn_factory(data, cfg)
mesh = make_mesh()
res = {"device_count": jax.device_count(), "mesh_devices": int(mesh.size)}
batch = shard_batch(batch_fn(0, jax.random.key(0)), mesh)
res["q_devices"] = len(batch["q"].sharding.device_set)
res["q_shard_rows"] = sorted({int(s.data.shape[0]) for s in batch["q"].addressable_shards})
res["length_replicated"] = bool(batch["length"].sharding.is_fully_replicated)

flat = {}
train = lambda name, n, m: run_training(init_fn, step_fn, batch_fn, cfg, f"{out}/{name}", n, log_every=1,
                                        ckpt_every=steps - 1, seed=0, progress=False, mesh=m)
for name, m in (("single", None), ("multi", mesh)):
    if m is None:   # uninterrupted
        state, logged = train(name, steps, m)
    else:           # stopped after the checkpoint at steps - 1, then resumed on the mesh
        _, logged = train(name, steps - 1, m)
        state, more = train(name, steps, m)
        res["resumed_steps"] = [row["step"] for row in more]
        logged += more
    res[name + "_loss"] = [row["loss"] for row in logged]
    res[name + "_param_devices"] = len(jax.tree.leaves(state["params"])[0].sharding.device_set)
    for path, leaf in jax.tree_util.tree_leaves_with_path({"params": state["params"], "disc": state["disc"]}):
        flat[name + jax.tree_util.keystr(path)] = np.asarray(leaf)
np.savez(f"{out}/params.npz", **flat)

# a batch of 3 rows cannot be split over 2 devices: refused before anything is compiled
bad_batch = lambda step, key: {"x": np.ones((3, 2), np.float32), "n": np.int32(3)}
try:
    run_training(lambda key: {"w": jax.numpy.zeros(2)}, lambda s, b, k: (s, {}), bad_batch, {}, f"{out}/bad", 1,
                 progress=False, mesh=mesh)
    res["error"] = None
except ValueError as e:
    res["error"] = str(e)
with open(f"{out}/result.json", "w") as f:
    json.dump(res, f)
"""


def test_two_device_data_parallel_matches_single_device(tmp_path):
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu")
    proc = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path), str(STEPS)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-4000:]
    with open(tmp_path / "result.json") as f:
        res = json.load(f)
    # two devices really took part
    assert res["device_count"] == 2 and res["mesh_devices"] == 2
    assert res["q_devices"] == 2 and res["q_shard_rows"] == [2] and res["length_replicated"]
    assert res["multi_param_devices"] == 2 and res["single_param_devices"] == 1
    assert res["resumed_steps"] == [STEPS]
    # same seed -> same losses and parameters up to float summation order (resume included)
    assert len(res["single_loss"]) == len(res["multi_loss"]) == STEPS
    np.testing.assert_allclose(res["multi_loss"], res["single_loss"], rtol=1e-4, atol=1e-5)
    flat = np.load(tmp_path / "params.npz")
    names = [k[len("single"):] for k in flat.files if k.startswith("single")]
    assert names and all("multi" + n in flat.files for n in names)
    print("max |param diff| single vs 2 devices:", max(float(np.abs(flat["multi" + n] - flat["single" + n]).max())
                                                       for n in names))
    for n in names:
        np.testing.assert_allclose(flat["multi" + n], flat["single" + n], rtol=1e-4, atol=1e-5, err_msg=n)
    # a batch that cannot be split evenly is refused with both numbers in the message
    assert res["error"] is not None and "3" in res["error"] and "2" in res["error"], res["error"]
    assert "divisible" in res["error"]
