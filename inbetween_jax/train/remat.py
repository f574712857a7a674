"""What the backward pass of an autoregressive rollout keeps from its forward pass (``model.remat``).

A ``lax.scan`` differentiated by JAX stacks every intermediate of every step that the backward pass reads: one
(steps, B, ...) buffer each (activations, the masks of each non-linearity, ...). XLA:CPU zero-fills each of those
buffers on every call by copying one shared zero buffer. In the S-CVAE's step at ``cpu`` widths these copies
write about 88 MB per step, and with the broadcasts they come from they took a third of the traced op time
(docs/results/speed.md, "2026-12-07: rematerialised rollouts").  ``jax.checkpoint`` on the step function with a
policy keeps fewer of them and recomputes the rest in the backward pass:

    ""         keep every intermediate (JAX's default)
    "dots"     keep the matmul outputs, recompute the element-wise ops after them (``dots_saveable``)
    "nothing"  keep only the carry, recompute the whole step (``nothing_saveable``)

The maths is unchanged: the losses and gradients agree to float tolerance (``tests/test_remat.py``).  Only the
time moves.  Without differentiation (sampling, inference) the wrapper changes nothing.
"""
from __future__ import annotations

from typing import Callable

import jax

__all__ = ["REMAT_POLICIES", "check_remat", "remat_step"]

REMAT_POLICIES = {"": None, "dots": jax.checkpoint_policies.dots_saveable,
                  "nothing": jax.checkpoint_policies.nothing_saveable}


def check_remat(policy: str) -> None:
    """Raise a one-line ``ValueError`` for a ``model.remat`` value that is not one of :data:`REMAT_POLICIES`."""
    if policy not in REMAT_POLICIES:
        raise ValueError(f"unknown model.remat {policy!r}; choose one of "
                         + ", ".join(repr(p) for p in REMAT_POLICIES))


def remat_step(step_fn: Callable, policy: str) -> Callable:
    """``step_fn`` (a ``lax.scan`` body) with its saved intermediates chosen by ``policy`` (module docstring);
    ``""`` returns it unchanged."""
    check_remat(policy)
    if not policy:
        return step_fn
    # inside a scan nothing is CSE'd across iterations, so JAX's CSE barrier is not needed (jax.checkpoint docs)
    return jax.checkpoint(step_fn, policy=REMAT_POLICIES[policy], prevent_cse=False)
