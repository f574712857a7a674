"""Training infrastructure shared by every model: configs, checkpoints, logging and the driver.

Public API::

    apply_overrides(config, ["a.b=3"]) -> config      config_to_dict(config) -> dict
    Checkpointer(directory, max_to_keep=3, save_every=1)  .save / .restore / .latest_step / .wait / .close
    MetricLogger(run_dir, resume_step=None)  .log(step, metrics) / .close      ProgressBar(total, initial)
    run_training(init_fn, train_step_fn, batch_fn, config, run_dir, num_steps, log_every, ckpt_every, seed)
    enable_compilation_cache(cache_dir=None) -> str
"""

from .checkpoint import Checkpointer
from .config import ConfigError, apply_overrides, config_to_dict, parse_value
from .logging import MetricLogger, ProgressBar, format_metrics
from .loop import default_cache_dir, enable_compilation_cache, make_step_fn, run_training

__all__ = [
    "Checkpointer", "ConfigError", "apply_overrides", "config_to_dict", "parse_value", "MetricLogger",
    "ProgressBar", "format_metrics", "default_cache_dir", "enable_compilation_cache", "make_step_fn",
    "run_training",
]
