"""Shared test fixtures: where the real mocap lives."""
import os

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
ASSETS = os.path.join(ROOT, "inbetween_jax", "assets", "cmu30")
CLIP_A, CLIP_B = os.path.join(ASSETS, "02_01.bvh"), os.path.join(ASSETS, "02_02.bvh")   # 86 and 76 frames

# Real LaFAN1 files: $LAFAN1_DIR, else the shared data folder beside the repository.
_DEFAULT = os.path.join(os.path.dirname(os.path.dirname(HERE)), "shared", "data", "lafan1")
LAFAN1_DIR = os.environ.get("LAFAN1_DIR") or _DEFAULT
SHARED_DATA = os.path.dirname(_DEFAULT)
HAS_LAFAN1 = os.path.isdir(LAFAN1_DIR) and any(f.endswith(".bvh") for f in os.listdir(LAFAN1_DIR))
requires_lafan1 = pytest.mark.skipif(not HAS_LAFAN1, reason="LaFAN1 BVH files not found (set LAFAN1_DIR)")

# Tests write their window caches into a private folder so they never reuse a user's cache.
os.environ.setdefault("INBETWEEN_JAX_CACHE", os.path.join(HERE, "..", ".cache", "test"))


@pytest.fixture(scope="session")
def cli_runs(tmp_path_factory) -> dict:
    """``{"scvae", "cae", "interaction"}`` tiny run folders on the embedded data, made once per session with
    ``inbetween_jax.runner.train_model``: the CAE trains 2 steps; the S-CVAE and interaction runs hold their
    initial state (``train.num_steps=0``: checkpoint 0, written without compiling a training step, which takes
    30-60 s on two cores for either).  ``test_cli_on_trained_runs`` (slow) covers trained ones."""
    from inbetween_jax.runner import train_model
    from inbetween_jax.train.loop import enable_compilation_cache
    enable_compilation_cache()
    base = tmp_path_factory.mktemp("cli_runs")
    runs = {}
    for model, steps in (("scvae", 0), ("cae", 2), ("interaction", 0)):
        runs[model] = str(base / model)
        train_model(model, "tiny", [f"train.num_steps={steps}", "train.ckpt_every=2", "train.log_every=2"],
                    "embedded", runs[model], progress=False, log=None)
    return runs


@pytest.fixture(scope="session")
def pair_train():
    """The training split of constructed pairs of the shipped CMU clips (interaction tests)."""
    from inbetween_jax.models.interaction import data as idata
    return idata.split_pairs(idata.load_pairs("embedded"), "train")


@pytest.fixture(scope="session")
def pair_windows():
    """Evaluation windows of the test split of those pairs: 20 context frames, a 30-frame gap and the keyframe
    (6 windows)."""
    from inbetween_jax.models.interaction import data as idata
    from inbetween_jax.models.interaction import batches as ibatches
    return ibatches.eval_windows(idata.split_pairs(idata.load_pairs("embedded"), "test"), 20, 30, 10, max_windows=6)


@pytest.fixture(scope="session")
def cae_fast_walk():
    """``(run, motion)``: the shipped CAE's run and CMU 02_01 from ``../shared/data/cmu_bvh`` (a walk at 1.2 m/s,
    120 Hz, 43 joints) on the run's skeleton at its rate, as ``inbetween infill`` prepares it."""
    from inbetween_jax.data import Skeleton, read_bvh
    from inbetween_jax.data.retarget import prepare
    from inbetween_jax.shipped import shipped_run
    path = os.path.join(SHARED_DATA, "cmu_bvh", "02_01.bvh")
    if not os.path.exists(path):
        pytest.skip("needs ../shared/data/cmu_bvh")
    run = shipped_run("cae")
    return run, prepare(read_bvh(path), path, Skeleton.from_dict(run.skeleton), run.fps).motion
