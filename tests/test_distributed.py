"""Multi-process training (``train.distributed``): 2 local CPU processes x 1 device reproduce 1 process.

The training runs in child processes started by :func:`launch_local`; this file is also the child
program (``python -m test_distributed --worker ...``, see :func:`worker`).  The model is a small MLP
that predicts the middle frame's joint rotations of a real CMU window (embedded clips) from its first
and last frames.  The children write their losses, parameters and facts about the global batch to an
npz per process, which the tests compare with a single-process run of the same script.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
STEPS, STOP = 6, 3          # the 2-process run stops after the checkpoint at STOP, then resumes to STEPS
BATCH, GAP, HIDDEN = 8, 10, 32


def _child_env() -> dict:
    path = os.pathsep.join([ROOT, HERE] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    return {"PYTHONPATH": path, "JAX_PLATFORMS": "cpu", "XLA_FLAGS": ""}


# ----------------------------------------------------------------------------- the child program
def worker(out: str, name: str, num_steps: int) -> None:
    """Train ``num_steps`` in ``out/name`` (resuming when checkpoints exist); write ``out/name.p<id>.npz``."""
    from inbetween_jax.train import distributed
    distributed.initialize()                        # before any JAX computation
    import jax
    import jax.numpy as jnp
    import optax
    from jax.experimental import multihost_utils
    from inbetween_jax.data import load_dataset
    from inbetween_jax.train import make_mesh, run_training, shard_batch

    q = np.asarray(load_dataset("embedded", "train").local_quats)          # (N, T, J, 4)
    n_win, n_frames = q.shape[:2]
    feat = q.shape[2] * 4
    opt = optax.adam(3e-3)

    def init_fn(key):
        k1, k2 = jax.random.split(key)
        params = {"w1": jax.random.normal(k1, (2 * feat, HIDDEN)) / np.sqrt(2 * feat), "b1": jnp.zeros(HIDDEN),
                  "w2": jax.random.normal(k2, (HIDDEN, feat)) / np.sqrt(HIDDEN), "b2": jnp.zeros(feat)}
        return {"params": params, "opt": opt.init(params)}

    def train_step(state, batch, key):
        def loss_fn(p):
            x = batch["x"] + 0.01 * jax.random.normal(key, batch["x"].shape)   # uses the step key
            pred = jnp.tanh(x @ p["w1"] + p["b1"]) @ p["w2"] + p["b2"]
            return jnp.mean((pred - batch["y"]) ** 2)
        loss, grads = jax.value_and_grad(loss_fn)(state["params"])
        updates, opt_state = opt.update(grads, state["opt"], state["params"])
        return {"params": optax.apply_updates(state["params"], updates), "opt": opt_state}, {"loss": loss}

    def batch_fn(step, key):
        """(step, key) -> {"x": (B, 2 * J * 4) first + last frame, "y": (B, J * 4) middle frame}."""
        kw, kt = jax.random.split(key)
        w = np.asarray(jax.random.randint(kw, (BATCH,), 0, n_win))
        t = np.asarray(jax.random.randint(kt, (BATCH,), 0, n_frames - GAP))
        x = np.concatenate([q[w, t].reshape(BATCH, -1), q[w, t + GAP].reshape(BATCH, -1)], axis=1)
        return {"x": x, "y": q[w, t + GAP // 2].reshape(BATCH, -1)}

    res = {"process_count": jax.process_count(), "device_count": jax.device_count()}
    mesh = make_mesh()
    global_batch = batch_fn(0, jax.random.key(1))
    sharded = shard_batch(global_batch, mesh)
    res["local_rows"] = sorted(int(s.data.shape[0]) for s in sharded["x"].addressable_shards)
    gathered = multihost_utils.process_allgather(sharded["x"], tiled=True)
    res["batch_bitwise"] = bool(np.array_equal(gathered, global_batch["x"]))

    state, logged = run_training(init_fn, train_step, batch_fn, {"name": name}, os.path.join(out, name),
                                 num_steps, log_every=1, ckpt_every=STOP, seed=0, progress=False,
                                 compilation_cache=False)
    res["steps"] = [r["step"] for r in logged]
    res["loss"] = [r["loss"] for r in logged]
    res["param_devices"] = len(state["params"]["w1"].sharding.device_set)
    params = {k: np.asarray(v) for k, v in state["params"].items()}
    np.savez(os.path.join(out, f"{name}.p{jax.process_index()}.npz"), res=json.dumps(res), **params)
    print(f"process {jax.process_index()} trained to step {num_steps}")


def _sleeper(pid_dir: str) -> None:
    """Child of the Ctrl-C test: records its pid, then waits to be stopped."""
    with open(os.path.join(pid_dir, f"{os.getpid()}.pid"), "w") as f:
        f.write(os.environ.get("INBETWEEN_PROCESS_ID", "?"))
    time.sleep(120)


if __name__ == "__main__":
    if sys.argv[1] == "--worker":
        worker(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    elif sys.argv[1] == "--exit":            # --exit CODE_OF_PROCESS_1
        pid = int(os.environ["INBETWEEN_PROCESS_ID"])
        print(f"stdout of process {pid}")
        print(f"stderr of process {pid}", file=sys.stderr)
        sys.exit(int(sys.argv[2]) if pid == 1 else 0)
    elif sys.argv[1] == "--sleep":
        _sleeper(sys.argv[2])
    sys.exit(0)


# ----------------------------------------------------------------------------- tests
def _launch(n: int, *args) -> int:
    from inbetween_jax.train.distributed import launch_local
    return launch_local(n, list(map(str, args)), module="test_distributed", env=_child_env())


def _load(path):
    with np.load(path) as f:
        return json.loads(str(f["res"])), {k: f[k] for k in f.files if k != "res"}


@pytest.mark.slow
def test_two_processes_match_one_process_with_resume(tmp_path, capfd):
    assert _launch(1, "--worker", tmp_path, "single", STEPS) == 0
    assert _launch(2, "--worker", tmp_path, "multi", STOP) == 0          # stop after the checkpoint at STOP
    assert _launch(2, "--worker", tmp_path, "multi", STEPS) == 0         # resume to STEPS
    out = capfd.readouterr().out
    assert "process 0 trained" in out and "process 1 trained" not in out  # only process 0 is heard

    single, ref = _load(tmp_path / "single.p0.npz")
    assert single["process_count"] == 1 and single["steps"] == list(range(1, STEPS + 1))
    assert single["batch_bitwise"] and single["local_rows"] == [BATCH]
    runs = [_load(tmp_path / f"multi.p{p}.npz") for p in (0, 1)]
    for res, params in runs:
        assert res["process_count"] == 2 and res["device_count"] == 2 and res["param_devices"] == 2
        assert res["local_rows"] == [BATCH // 2]          # each process holds only its half of the batch
        assert res["batch_bitwise"]                        # ... and the halves form the single-process batch
        assert res["steps"] == list(range(STOP + 1, STEPS + 1))
        for k in ref:                                      # replicated: both processes hold the same values
            np.testing.assert_array_equal(params[k], runs[0][1][k], err_msg=k)
    # losses of the resumed steps and final parameters match the uninterrupted 1-process run
    np.testing.assert_allclose(runs[0][0]["loss"], single["loss"][STOP:], rtol=1e-6, atol=1e-7)
    for k in ref:
        np.testing.assert_allclose(runs[0][1][k], ref[k], rtol=1e-6, atol=1e-6, err_msg=k)
    # process 0 alone wrote the metric files; the first half comes from the stopped run
    rows = [json.loads(line) for line in open(tmp_path / "multi" / "metrics.jsonl")]
    assert [r["step"] for r in rows] == list(range(1, STEPS + 1))
    np.testing.assert_allclose([r["loss"] for r in rows], single["loss"], rtol=1e-6, atol=1e-7)
    assert sorted(os.listdir(tmp_path / "multi" / "checkpoints")) == [str(STOP), str(STEPS)]


def test_launch_local_returns_first_failure_and_keeps_others_quiet(capfd):
    assert _launch(2, "--exit", 0) == 0
    cap = capfd.readouterr()
    assert "stdout of process 0" in cap.out and "stderr of process 0" in cap.err
    assert "process 1" not in cap.out + cap.err
    assert _launch(2, "--exit", 3) == 3
    cap = capfd.readouterr()
    assert "[process 1] stderr of process 1" in cap.err       # a failing process's stderr is shown
    assert "stdout of process 1" not in cap.out


@pytest.mark.parametrize("watcher", [False, True])
def test_launch_local_ctrl_c_stops_every_process(tmp_path, watcher):
    """SIGINT to the launcher alone (not its process group) stops both children.  ``watcher``: as the CLI runs
    it (``train --num-processes 2``), under the Ctrl-C watcher, which ends the launcher at once with status 130
    and must stop the children it was given."""
    hooks = "on_interrupt=interrupt.at_exit, report=interrupt.say" if watcher else ""
    # as a terminal starts it: SIGINT handled (a shell running the tests in the background has it ignored, and a
    # child inherits that); then the watcher, as the CLI does, before JAX starts threads that could take the signal
    code = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
            "from inbetween_jax.cli import interrupt; "
            + ("interrupt.install(); " if watcher else "")
            + "from inbetween_jax.train.distributed import launch_local; "
            + f"sys.exit(launch_local(2, ['--sleep', {str(tmp_path)!r}], module='test_distributed', "
            f"env={_child_env()!r}, {hooks}))")
    # an earlier test's CLI call may have left SIGINT blocked in this process (inbetween_jax.cli.interrupt), and a
    # child inherits the blocked mask
    from inbetween_jax.train.distributed import sigint_unblocked
    with sigint_unblocked():
        launcher = subprocess.Popen([sys.executable, "-c", code], env=dict(os.environ, **_child_env()), cwd=ROOT)
    deadline = time.monotonic() + 60
    while len(os.listdir(tmp_path)) < 2 and time.monotonic() < deadline:
        time.sleep(0.1)
    children = [int(f.split(".")[0]) for f in os.listdir(tmp_path)]
    assert sorted(open(tmp_path / f"{c}.pid").read() for c in children) == ["0", "1"]
    launcher.send_signal(signal.SIGINT)
    assert launcher.wait(timeout=60) == 130
    for c in children:                                   # the children are gone (reaped by the launcher)
        with pytest.raises(ProcessLookupError):
            os.kill(c, 0)


def test_initialize_single_process_is_a_noop(monkeypatch):
    from inbetween_jax.train import distributed
    for var in (distributed.ENV_COORDINATOR, distributed.ENV_NUM_PROCESSES, distributed.ENV_PROCESS_ID,
                "JAX_COORDINATOR_ADDRESS", "SLURM_JOB_ID", "OMPI_MCA_orte_hnp_uri", "JOB_COMPLETION_INDEX",
                "TPU_PROCESS_ADDRESSES", "TPU_WORKER_HOSTNAMES"):
        monkeypatch.delenv(var, raising=False)
    assert distributed.initialize() == (0, 1)
    assert distributed.initialize(num_processes=1) == (0, 1)
    with pytest.raises(ValueError, match="must be >= 1"):
        distributed.initialize(num_processes=0)
    monkeypatch.setenv(distributed.ENV_NUM_PROCESSES, "two")
    with pytest.raises(ValueError, match="INBETWEEN_NUM_PROCESSES='two' is not an integer"):
        distributed.initialize()


@pytest.mark.slow
def test_cli_two_processes_match_one_including_resume(tmp_path):
    """``inbetween train cae --num-processes 2`` (stopped at step 3, resumed to 6) logs the losses of one process."""
    import csv

    def train(run_dir, steps, procs):
        argv = [sys.executable, "-m", "inbetween_jax.cli", "train", "cae", "--preset", "tiny", "--source", "embedded",
                "--run-dir", str(run_dir), "--no-progress", "--num-processes", str(procs), f"train.num_steps={steps}",
                "train.log_every=1", "train.ckpt_every=3"]
        res = subprocess.run(argv, capture_output=True, text=True, timeout=600, cwd=tmp_path)
        assert res.returncode == 0, res.stderr[-2000:]

    def losses(run_dir):
        with open(run_dir / "metrics.csv") as f:
            return [(int(r["step"]), float(r["loss"]), float(r["hole_l1"])) for r in csv.DictReader(f)]

    train(tmp_path / "one", 6, 1)
    train(tmp_path / "two", 3, 2)
    train(tmp_path / "two", 6, 2)
    one, two = losses(tmp_path / "one"), losses(tmp_path / "two")
    assert [s for s, _, _ in one] == [s for s, _, _ in two] == list(range(1, 7))
    np.testing.assert_allclose(np.array(two)[:, 1:], np.array(one)[:, 1:], rtol=1e-6, atol=1e-6)
