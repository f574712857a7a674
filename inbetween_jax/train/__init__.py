"""Training infrastructure shared by every model: configs, optimiser, run folders, checkpoints, logging, driver.

Public API (names are imported on first use, so ``inbetween_jax.train.config`` stays free of JAX)::

    TrainConfig                                   the ``train`` config group, identical for every model
    apply_overrides(config, ["a.b=3"]) -> config  config_to_dict / config_from_dict / describe_config
    make_optimizer(cfg.train)                     Adam / AdamW, clip, constant or cosine lr
    write_run / load_run / restore_state          the one run-folder format (run.json + checkpoints/)
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
import importlib

_NAMES = {
    "Checkpointer": "checkpoint", "CheckpointError": "checkpoint",
    "ConfigError": "config", "TrainConfig": "config", "apply_overrides": "config", "config_from_dict": "config",
    "config_to_dict": "config", "describe_config": "config", "parse_value": "config",
    "MetricLogger": "logging", "ProgressBar": "logging", "format_metrics": "logging",
    "default_cache_dir": "loop", "enable_compilation_cache": "loop", "make_step_fn": "loop", "run_training": "loop",
    "make_mesh": "parallel", "make_parallel_step_fn": "parallel", "replicate": "parallel", "shard_batch": "parallel",
    "make_optimizer": "optim",
    "Run": "run", "RunError": "run", "load_run": "run", "restore_state": "run", "write_run": "run",
}
__all__ = sorted(_NAMES) + ["data_parallel", "distributed"]


def __getattr__(name):
    if name == "data_parallel":
        return importlib.import_module("inbetween_jax.train.parallel")
    if name == "distributed":
        return importlib.import_module("inbetween_jax.train.distributed")
    if name in _NAMES:
        return getattr(importlib.import_module(f"inbetween_jax.train.{_NAMES[name]}"), name)
    raise AttributeError(f"module 'inbetween_jax.train' has no attribute {name!r}")
