"""The optimiser every model builds from its ``train`` config group (:class:`~inbetween_jax.train.config.TrainConfig`).

    tx = make_optimizer(cfg.train)      # optax.GradientTransformation

Adam (AdamW when ``weight_decay > 0``), behind ``clip_by_global_norm(grad_clip)`` when ``grad_clip > 0``, with
a constant or warm-up + cosine learning rate.  With ``lr_schedule="constant"`` and ``warmup_steps=0`` the
learning rate is the plain float ``lr`` (no schedule object, no step counter in the optimiser state).

With ``ema_decay`` d > 0 the optimiser state also carries an exponential moving average of the parameters after
every update (Polyak averaging; :func:`with_ema`), which inference reads instead of the last parameters
(:func:`inference_params`, unless ``train.ema_eval=false``).  It lives in the optimiser state, so orbax saves it
with every checkpoint and a resumed run continues it exactly; training itself is unchanged.
"""
from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax

from .config import ConfigError, TrainConfig

__all__ = ["learning_rate", "make_optimizer", "EmaState", "with_ema", "inference_params"]


class EmaState(NamedTuple):
    """:func:`with_ema`'s optimiser state: the wrapped optimiser's, the number of updates and the average."""
    inner: Any
    count: jax.Array
    ema: Any


def with_ema(inner: optax.GradientTransformation, decay: float) -> optax.GradientTransformation:
    """``inner`` with an exponential moving average of the updated parameters in its state (needs ``params`` in
    ``update``): after update n (1-based), ``ema <- d_n ema + (1 - d_n) params_n`` with ``d_n = min(decay,
    (1 + n) / (10 + n))``, the warm-up of TensorFlow's ``ExponentialMovingAverage`` (num_updates), so the
    initial parameters leave the average within the first tens of updates.  The updates are ``inner``'s."""
    decay = float(decay)

    def init(params):
        return EmaState(inner.init(params), jnp.zeros((), jnp.int32), jax.tree.map(jnp.array, params))

    def update(grads, state, params=None):
        if params is None:
            raise ValueError("with_ema needs the parameters in update()")
        updates, inner_state = inner.update(grads, state.inner, params)
        count = state.count + 1
        c = count.astype(jnp.float32)
        d = jnp.minimum(decay, (1.0 + c) / (10.0 + c))
        new = optax.apply_updates(params, updates)
        ema = jax.tree.map(lambda e, p: (d * e + (1.0 - d) * p).astype(e.dtype), state.ema, new)
        return updates, EmaState(inner_state, count, ema)

    return optax.GradientTransformation(init, update)


def inference_params(params, opt_state, tc: TrainConfig | None = None):
    """The parameters inference uses: the moving average in ``opt_state`` (an :class:`EmaState`, possibly under a
    leading member axis) when it holds one that has seen an update and ``tc.ema_eval`` is on; else ``params``.
    A shipped run's optimiser state is restored as zeros (count 0), so its ``params`` (exported from the average)
    are used as they are."""
    if tc is not None and not getattr(tc, "ema_eval", True):
        return params
    found = [s for s in jax.tree.leaves(opt_state, is_leaf=lambda x: isinstance(x, EmaState))
             if isinstance(s, EmaState)]
    if not found or not bool(jnp.all(jnp.asarray(found[0].count) > 0)):
        return params
    return found[0].ema


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
    """Adam / AdamW of the ``train`` group (see the module docstring), with the parameters' moving average when
    ``ema_decay`` > 0."""
    lr = learning_rate(tc)
    if tc.weight_decay > 0:
        opt = optax.adamw(lr, b1=tc.b1, b2=tc.b2, weight_decay=tc.weight_decay)
    else:
        opt = optax.adam(lr, b1=tc.b1, b2=tc.b2)
    if tc.grad_clip > 0:
        opt = optax.chain(optax.clip_by_global_norm(tc.grad_clip), opt)
    ema = float(getattr(tc, "ema_decay", 0.0))
    if ema < 0 or ema >= 1:
        raise ConfigError(f"bad value for config key 'train.ema_decay': expected 0 (off) or a number in (0, 1), "
                          f"got {ema!r}")
    return with_ema(opt, ema) if ema > 0 else opt
