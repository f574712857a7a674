"""The benchmark helpers of :mod:`inbetween_jax.profiling`: FLOP counts against hand counts (a scan body counted
once per step), and the op-time table of a profiler trace."""
from __future__ import annotations

import re

import jax
import jax.numpy as jnp
import numpy as np

from inbetween_jax.profiling import matmul_flops, op_ms_by_kind


def test_matmul_flops_counts_each_scan_step_and_convs():
    a, b = jnp.ones((4, 5)), jnp.ones((5, 3))

    def scanned(a, b):
        return jax.lax.scan(lambda c, _: (c + (a @ b).sum(), None), 0.0, None, length=7)[0]
    assert matmul_flops(scanned, a, b) == 7 * 2 * 4 * 5 * 3
    x, w = jnp.ones((1, 8, 8, 2)), jnp.ones((3, 3, 2, 3))
    conv = lambda x, w: jax.lax.conv_general_dilated(x, w, (1, 1), "SAME",                 # noqa: E731
                                                     dimension_numbers=("NHWC", "HWIO", "NHWC"))
    assert matmul_flops(conv, x, w) == 2 * (8 * 8 * 3) * (3 * 3 * 2)


def test_op_time_names_xla_ops_only_and_finds_the_expensive_one():
    x = jax.random.normal(jax.random.key(0), (200_000,))
    f = jax.jit(lambda x: jnp.sort(x) * 2.0)
    wall, kinds, covered = op_ms_by_kind(lambda: f(x), calls=3)
    assert kinds and all(re.fullmatch(r"[a-z][a-z0-9_-]*", k) for k in kinds)     # no runtime spans or frames
    assert next(iter(kinds)) == "sort"                                             # largest first
    assert list(kinds.values()) == sorted(kinds.values(), reverse=True)
    assert 0 < kinds["sort"] <= 1.5 * wall and np.isfinite(wall)
    assert kinds["sort"] <= covered + 1e-6 and covered <= sum(kinds.values()) + 1e-6   # one op at a time here
