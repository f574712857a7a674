"""The XLA:CPU settings of the ``inbetween`` command (:mod:`inbetween_jax.xla_cpu`)."""
import os
import subprocess
import sys

import pytest

from inbetween_jax import xla_cpu


def test_configure_adds_the_models_flag_once_and_respects_the_user(monkeypatch):
    monkeypatch.setattr(xla_cpu, "_jaxlib_version", lambda: "0.10.2")
    env = {"XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    assert xla_cpu.configure("cae", env)
    assert env["XLA_FLAGS"] == f"--xla_force_host_platform_device_count=2 {xla_cpu.FLAG}=individual_dot"
    assert not xla_cpu.configure("interaction", env) and env["XLA_FLAGS"].count(xla_cpu.FLAG) == 1
    inter = {}
    assert xla_cpu.configure("interaction", inter) and inter["XLA_FLAGS"] == f"{xla_cpu.FLAG}="
    own = {"XLA_FLAGS": f"{xla_cpu.FLAG}=individual_convolution"}
    assert not xla_cpu.configure("cae", own) and own["XLA_FLAGS"].endswith("=individual_convolution")
    opt_out = {xla_cpu.OPT_OUT_ENV: "1"}
    assert not xla_cpu.configure(None, opt_out) and "XLA_FLAGS" not in opt_out


def test_configure_leaves_an_unmeasured_jaxlib_alone(monkeypatch):
    monkeypatch.setattr(xla_cpu, "_jaxlib_version", lambda: "0.11.0")
    env = {}
    assert not xla_cpu.configure("cae", env) and env == {}


@pytest.mark.parametrize("argv, model", [(["train", "cae", "--preset", "cpu"], "cae"), (["train", "--help"], None),
                                         (["infill", "--model", "interaction", "--out", "o"], "interaction"),
                                         (["infill", "--model=scvae"], "scvae"), (["bench"], None)])
def test_model_in_argv(argv, model):
    assert xla_cpu.model_in_argv(argv) == model


@pytest.mark.parametrize("model", ["interaction", None])
def test_the_installed_jaxlib_accepts_the_flag(model):
    """An unknown flag in XLA_FLAGS aborts the process at backend start: run a computation under it."""
    env = dict(os.environ)
    env.pop("XLA_FLAGS", None)
    env.pop(xla_cpu.OPT_OUT_ENV, None)
    code = (f"from inbetween_jax import xla_cpu; import os; assert xla_cpu.configure({model!r}); "
            "import jax.numpy as jnp; print(float(jnp.ones((8, 8)).sum()), os.environ['XLA_FLAGS'])")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.startswith("64.0") and xla_cpu.flag_for(model) in out.stdout
