"""S-CVAE training tests on real CMU windows: overfitting, determinism, resume after an interruption, and the
run-folder round trip (train_model -> load_run -> infer.load -> sampling / infill)."""
import csv
import os
import signal
import subprocess
import sys
import time

import jax
import numpy as np
import pytest

from inbetween_jax.data import load_dataset
from inbetween_jax.models.scvae import train as T
from inbetween_jax.models.scvae.config import get_config
from inbetween_jax.models.scvae.features import TrainData, compute_stats
from inbetween_jax.train import apply_overrides, run_training

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CFG = apply_overrides(get_config("tiny"), ["train.lr=3e-3", "data.trans_start=10", "data.trans_max=10"])
STEPS = 200


@pytest.fixture(scope="module")
def pieces():
    everything = load_dataset(None, "train")
    windows = everything.take(slice(0, 4))
    data = TrainData.from_windows(windows)
    max_length = CFG.data.trans_max + 1
    fixed = T.make_batch(data, np.arange(4), np.array([0, 5, 10, 20]), max_length, max_length)  # 4 real windows
    init_fn = T.make_init_fn(CFG, compute_stats(everything), data.q.shape[2])
    step_fn = T.make_train_step(CFG, data.parents, max_length)
    return init_fn, step_fn, (lambda step, key: fixed)


@pytest.fixture(scope="module")
def jitted(pieces):
    init_fn, step_fn, batch_fn = pieces
    return jax.jit(init_fn), jax.jit(step_fn), batch_fn


def _losses_of(jitted, steps, seed):
    init, step, batch_fn = jitted
    state = init(jax.random.key(seed))
    out = []
    for i in range(steps):
        state, m = step(state, batch_fn(i, None), jax.random.fold_in(jax.random.key(seed + 1), i))
        out.append(jax.device_get(m))
    return out


def test_tiny_model_overfits_and_is_deterministic(jitted):
    hist = _losses_of(jitted, STEPS, 0)
    recon = np.array([m["state"] + m["fk"] for m in hist])
    fk = np.array([m["fk"] for m in hist])
    assert np.all(np.isfinite(recon))
    first, last = recon[:5].mean(), recon[-10:].mean()
    print(f"recon {first:.3f} -> {last:.3f}; fk {fk[:5].mean():.3f} -> {fk[-10:].mean():.3f}")
    assert first / last > 4.0, f"reconstruction loss only fell from {first:.3f} to {last:.3f}"
    assert fk[:5].mean() / fk[-10:].mean() > 5.0, "FK loss did not fall by 5x"
    # a fixed seed reproduces the run exactly; another seed does not
    again = _losses_of(jitted, 3, 0)
    for a, b in zip(again, hist[:3]):
        assert all(np.array_equal(a[k], b[k]) for k in a)
    other = _losses_of(jitted, 2, 7)
    assert other[1]["loss"] != hist[1]["loss"]


def _csv_losses(run_dir):
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        return {int(r["step"]): float(r["loss"]) for r in csv.DictReader(f)}


@pytest.mark.slow
def test_resume_continues_the_same_loss_curve(pieces, tmp_path):
    """run_training stopped after a checkpoint and restarted reproduces the uninterrupted curve."""
    init_fn, step_fn, batch_fn = pieces
    run = lambda d, n, every: run_training(init_fn, step_fn, batch_fn, CFG, str(tmp_path / d), n, log_every=1,
                                           ckpt_every=every, seed=0, progress=False)[1]
    clean = run("clean", 6, 6)
    first = run("resumed", 3, 3)       # the process dies after the step-3 checkpoint
    rest = run("resumed", 6, 3)        # restart: resumes from it
    assert [r["step"] for r in rest] == [4, 5, 6]
    for a, b in zip(first + rest, clean):
        assert a["step"] == b["step"] and a["loss"] == pytest.approx(b["loss"], rel=1e-5)
    assert sorted(_csv_losses(str(tmp_path / "resumed"))) == [1, 2, 3, 4, 5, 6]


TRAIN_CHILD = """
import sys
from inbetween_jax.runner import train_model
train_model("scvae", "tiny", ["train.num_steps=12", "train.ckpt_every=4", "train.log_every=1",
                              "data.trans_start=10", "data.trans_max=10"],
            source="embedded", run_dir=sys.argv[1], progress=False, log=None)
"""


@pytest.mark.slow
def test_sigkill_and_restart_of_training_continues_the_curve(tmp_path):
    """``runner.train_model`` killed with SIGKILL after a checkpoint, restarted, matches a clean run."""
    clean, killed = str(tmp_path / "clean"), str(tmp_path / "killed")
    cmd = [sys.executable, "-c", TRAIN_CHILD]
    subprocess.run(cmd + [clean], check=True, cwd=ROOT)
    proc = subprocess.Popen(cmd + [killed], cwd=ROOT)
    deadline = time.time() + 600
    while time.time() < deadline and not os.path.isdir(os.path.join(killed, "checkpoints", "4")):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert len(_csv_losses(killed)) < 12
    subprocess.run(cmd + [killed], check=True, cwd=ROOT)
    a, b = _csv_losses(clean), _csv_losses(killed)
    assert sorted(b) == list(range(1, 13))
    for s in range(1, 13):
        assert a[s] == pytest.approx(b[s], rel=1e-5)


def test_run_folder_round_trip_load_sample_and_infill(tmp_path):
    """train_model writes a run folder; infer.load rebuilds the model from it alone (no training data) and
    samples finite transitions of the right shape, on benchmark windows and between two BVH keyframes."""
    import argparse

    from inbetween_jax.data import read_bvh
    from inbetween_jax.data.datasets import EMBEDDED_DIR
    from inbetween_jax.models.scvae import infer
    from inbetween_jax.models.spec import InfillResult
    from inbetween_jax.runner import train_model
    from inbetween_jax.train.run import load_run
    run_dir = str(tmp_path / "run")
    overrides = ["train.num_steps=2", "train.ckpt_every=2", "train.log_every=1"]
    _, logged = train_model("scvae", "tiny", overrides, source="embedded", run_dir=run_dir, progress=False, log=None)
    assert [r["step"] for r in logged] == [1, 2] and all(np.isfinite(r["loss"]) for r in logged)
    run = load_run(run_dir)
    assert run.model == "scvae" and run.step == 2 and run.extra["num_joints"] == 21
    assert set(run.stats) == {"v_std", "off_std", "pos_unit", "offsets"} and run.stats["offsets"].shape == (21, 3)
    trained = infer.load(run)
    assert trained.cfg == apply_overrides(get_config("tiny"), overrides) and trained.step == 2
    # the restored statistics are the run's (not the zero restore target)
    np.testing.assert_allclose(np.asarray(trained.stats["v_std"]), run.stats["v_std"], rtol=1e-6)
    windows = load_dataset(None, "benchmark").take(slice(0, 3))
    n_trans = 8
    s = infer.sample_transitions(trained.cfg.model, trained.state, windows, 10, n_trans, num_samples=2)
    assert s["q"].shape == (2, 3, n_trans, 21, 4) and s["r"].shape == (2, 3, n_trans, 3)
    assert s["mid_f"].shape == (2, 3, 21, 3) and all(np.all(np.isfinite(v)) for v in s.values())
    bvh = sorted(f for f in os.listdir(EMBEDDED_DIR) if f.endswith(".bvh"))[0]
    path = os.path.join(EMBEDDED_DIR, bvh)
    motion = read_bvh(path)
    args = argparse.Namespace(start=f"{path}:0", end=f"{path}:30", frames=6, samples=2, seed=0)
    res = infer.infill(args, run)
    assert isinstance(res, InfillResult) and [name for name, _, _ in res.samples] == ["sample_00", "sample_01"]
    for _, motions, _ in res.samples:
        m = motions[0]
        assert m.local_quats.shape == (8, 21, 4) and np.all(np.isfinite(m.local_quats))
        np.testing.assert_allclose(m.local_quats[0], motion.local_quats[0], atol=1e-6)   # exact keyframes
        np.testing.assert_allclose(m.root_pos[-1], motion.root_pos[30], atol=1e-6)
    assert res.summary["step"] == 2 and res.summary["frames"] == 6
    from inbetween_jax.errors import UserError
    with pytest.raises(UserError, match="--frames 11"):
        infer.infill(argparse.Namespace(**dict(vars(args), frames=11)), run)
