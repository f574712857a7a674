"""The un-jitted training step shared by the single-device driver, the data-parallel step and sweeps.

Kept apart from ``train.loop`` and ``train.parallel`` so both import it without importing each other.
"""
from __future__ import annotations

from typing import Any, Callable

import jax
import jax.numpy as jnp

__all__ = ["step_body", "strongly_typed"]


def strongly_typed(x: Any) -> Any:
    """Leaf -> jax.Array without weak type, so init / restored / stepped states share one jit signature."""
    if isinstance(x, jax.Array) and jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key):
        return x
    return jnp.asarray(x, dtype=jnp.result_type(x))


def _signature(tree: Any) -> Any:
    return jax.tree.map(lambda x: (tuple(jnp.shape(x)), jnp.result_type(x)), tree)


def step_body(train_step_fn: Callable) -> Callable:
    """Un-jitted ``(state, batch, i, base) -> (state, metrics)`` with the step key ``fold_in(base, i)``.

    The base key is an argument, not a constant baked into the program, so runs with different seeds
    share one compiled executable (and one persistent-cache entry).  The returned state must keep the
    input's structure, shapes and dtypes (checked at trace time, otherwise every step would recompile).
    """

    def step(state, batch, i, base):
        key = jax.random.fold_in(base, i)
        new_state, metrics = train_step_fn(state, batch, key)
        new_state = jax.tree.map(strongly_typed, new_state)
        if jax.tree.structure(new_state) != jax.tree.structure(state) or _signature(new_state) != _signature(state):
            raise TypeError("train_step_fn must return a state with the same structure, shapes and dtypes as "
                            f"its input; got {_signature(new_state)} for {_signature(state)}")
        return new_state, dict(metrics)

    return step
