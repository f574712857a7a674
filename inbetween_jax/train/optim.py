"""The optimiser every model builds from its ``train`` config group (:class:`~inbetween_jax.train.config.TrainConfig`).

    tx = make_optimizer(cfg.train)      # optax.GradientTransformation

Adam (AdamW when ``weight_decay > 0``), behind ``clip_by_global_norm(grad_clip)`` when ``grad_clip > 0``, with
a constant or warm-up + cosine learning rate.  With ``lr_schedule="constant"`` and ``warmup_steps=0`` the
learning rate is the plain float ``lr`` (no schedule object, no step counter in the optimiser state).
"""
from __future__ import annotations

import optax

from .config import ConfigError, TrainConfig

__all__ = ["learning_rate", "make_optimizer"]


def learning_rate(tc: TrainConfig):
    """``lr`` (float) or an ``optax`` schedule ``step -> lr``."""
    if tc.lr_schedule == "constant":
        if tc.warmup_steps <= 0:
            return tc.lr
        return optax.join_schedules([optax.linear_schedule(0.0, tc.lr, tc.warmup_steps), optax.constant_schedule(tc.lr)],
                                    [tc.warmup_steps])
    if tc.lr_schedule == "cosine":
        return optax.warmup_cosine_decay_schedule(0.0 if tc.warmup_steps > 0 else tc.lr, tc.lr,
                                                  max(tc.warmup_steps, 1), max(tc.num_steps, tc.warmup_steps + 1),
                                                  end_value=tc.lr * tc.lr_final)
    raise ConfigError(f"bad value for config key 'train.lr_schedule': expected constant or cosine, "
                      f"got {tc.lr_schedule!r}")


def make_optimizer(tc: TrainConfig) -> optax.GradientTransformation:
    """Adam / AdamW of the ``train`` group (see the module docstring)."""
    lr = learning_rate(tc)
    if tc.weight_decay > 0:
        opt = optax.adamw(lr, b1=tc.b1, b2=tc.b2, weight_decay=tc.weight_decay)
    else:
        opt = optax.adam(lr, b1=tc.b1, b2=tc.b2)
    if tc.grad_clip > 0:
        return optax.chain(optax.clip_by_global_norm(tc.grad_clip), opt)
    return opt
