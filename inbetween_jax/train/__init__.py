"""Training infrastructure shared by every model: configs, checkpoints, logging and the driver.

Public API::

    apply_overrides(config, ["a.b=3"]) -> config      config_to_dict(config) -> dict
    Checkpointer(directory, max_to_keep=3, save_every=1)  .save / .restore / .latest_step / .wait / .close
    MetricLogger(run_dir, resume_step=None)  .log(step, metrics) / .close      ProgressBar(total, initial)
    run_training(init_fn, train_step_fn, batch_fn, config, run_dir, num_steps, log_every, ckpt_every, seed)
    enable_compilation_cache(cache_dir=None) -> str
    data-parallel (``data_parallel`` is the ``train.parallel`` module): make_mesh(num_devices=None) -> Mesh,
    shard_batch(batch, mesh), replicate(state, mesh), make_parallel_step_fn(step_fn, train_base, mesh);
    run_training(..., mesh=make_mesh()) trains with the state replicated and every batch split.
    several processes (``train.distributed``): initialize() first thing, launch_local(n, argv, module);
    the same run_training call then trains on the global mesh of all processes.
    CheckpointError (a ValueError): damaged or missing checkpoints, one line naming the folder.
"""

from .checkpoint import Checkpointer, CheckpointError
from .config import ConfigError, apply_overrides, config_to_dict, parse_value
from .logging import MetricLogger, ProgressBar, format_metrics
from .loop import default_cache_dir, enable_compilation_cache, make_step_fn, run_training
from . import distributed
from . import parallel as data_parallel
from .parallel import make_mesh, make_parallel_step_fn, replicate, shard_batch

__all__ = [
    "Checkpointer", "CheckpointError", "ConfigError", "apply_overrides", "config_to_dict", "parse_value",
    "MetricLogger", "ProgressBar", "format_metrics", "default_cache_dir", "enable_compilation_cache",
    "make_step_fn", "run_training", "data_parallel", "make_mesh", "make_parallel_step_fn", "replicate",
    "shard_batch", "distributed",
]
