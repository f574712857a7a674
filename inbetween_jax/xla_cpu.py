"""XLA:CPU settings measured faster for this project's models (docs/results/speed.md, "YNNPACK fusions").

XLA:CPU hands dots and convolutions to YNNPACK by default.  On this project's training steps (medians of 9
steps, one process per setting, ranges over 2-6 processes, ms; ``experiments/cae_step_speed.py flags``):

    XLA_FLAGS --xla_cpu_experimental_ynn_fusion_type=   default     individual_dot   (empty: none)
    CAE ``improved``, batch 16                          167-192     147-171          149-152
    interaction ``improved``, 3 members                1120-1199   1141-1231         980-1146 (median 1018)
    S-CVAE ``cpu`` widths, batch 32                     161-189     166-170          198-275
    S-CVAE ``paper`` widths, batch 32                  1696-1781   1761-1780        2804-2878

So the CAE's convolutions are faster in XLA's own (Eigen) kernels, the interaction model is faster with no
YNNPACK at all, and the S-CVAE's large matmuls need YNNPACK's dots.  :func:`configure` sets the flag for the
model a process runs: ``""`` for the interaction model, ``individual_dot`` (YNNPACK for dots only) otherwise.
The ``inbetween`` command (with the model its arguments name) and the experiments that train or time call it
before JAX creates its CPU backend; a library user may call it too.  It changes nothing when the user's
``XLA_FLAGS`` already sets that flag, when ``INBETWEEN_XLA_DEFAULTS=1`` asks for XLA's defaults, or when the
installed jaxlib is not the pinned release the flag was measured on (an unknown flag in ``XLA_FLAGS`` aborts the
process).
"""
from __future__ import annotations

import os
from importlib import metadata

__all__ = ["FLAG", "YNN_FUSIONS", "DEFAULT_FUSIONS", "OPT_OUT_ENV", "MEASURED_JAXLIB", "flag_for", "configure",
           "model_in_argv"]

FLAG = "--xla_cpu_experimental_ynn_fusion_type"
YNN_FUSIONS = {"interaction": ""}     # model -> the flag's value; any other model (or None): DEFAULT_FUSIONS
DEFAULT_FUSIONS = "individual_dot"
OPT_OUT_ENV = "INBETWEEN_XLA_DEFAULTS"
MEASURED_JAXLIB = ("0.10.",)          # the flag exists (and was measured) in these jaxlib releases


def _jaxlib_version() -> str:
    try:
        return metadata.version("jaxlib")
    except metadata.PackageNotFoundError:
        return ""


def flag_for(model=None) -> str:
    """The ``XLA_FLAGS`` entry for a process that runs ``model`` (a registry name, or None for several)."""
    return f"{FLAG}={YNN_FUSIONS.get(model, DEFAULT_FUSIONS)}"


def configure(model=None, environ=None) -> bool:
    """Add :func:`flag_for` ``(model)`` to ``environ["XLA_FLAGS"]`` (default ``os.environ``); True when added.

    Must run before JAX's first computation (the CPU backend reads ``XLA_FLAGS`` once, when it is created)."""
    env = os.environ if environ is None else environ
    flags = env.get("XLA_FLAGS", "")
    if env.get(OPT_OUT_ENV) == "1" or FLAG in flags:
        return False
    if not _jaxlib_version().startswith(MEASURED_JAXLIB):
        return False
    env["XLA_FLAGS"] = f"{flags} {flag_for(model)}".strip()
    return True


def model_in_argv(argv) -> str | None:
    """The model an ``inbetween`` command line runs (``train MODEL``, ``--model MODEL``), else None."""
    argv = list(argv)
    if len(argv) >= 2 and argv[0] == "train" and not argv[1].startswith("-"):
        return argv[1]
    for i, a in enumerate(argv):
        if a == "--model" and i + 1 < len(argv):
            return argv[i + 1]
        if a.startswith("--model="):
            return a.split("=", 1)[1]
    return None
