"""The model contract: what every model package provides, and the :class:`Training` it hands to the driver.

A model is a package ``inbetween_jax/models/<name>/`` with these files (roles), resolved by name::

    config.py    PRESETS, DEFAULT_PRESET, get_config(preset) -> Config(model, data, loss, train)
    features.py  the model's representation (motion <-> network arrays)
    model.py     init_params(key, cfg, ...) -> params (nested dict of arrays); pure apply functions
    losses.py    pure loss functions
    train.py     load_data(cfg, source, split="train") -> data;  make_training(cfg, data) -> Training
    infer.py     load(run) -> trained model;  infill(args, run) -> InfillResult (``inbetween infill``)
    bench.py     run(source, results_dir, run_dir, quick) -> {"markdown": str, "rows": [record, ...], ...}

``__init__.py`` holds the docstring and ``INFILL_OPTIONS = {dest: (metavar, help)}``, the ``inbetween infill``
options the model needs (metavar ``N``: an int; ``FILE...``: a file the CLI checks before loading anything;
``START:STOP...``: a gap list, syntax-checked the same way), and
imports nothing heavy.  Plus one line in :data:`inbetween_jax.models.REGISTRY`.  Nothing here imports a model (or JAX) until a role
is used, so ``inbetween train MODEL --help`` and argument errors are instant.
"""
from __future__ import annotations

import dataclasses
import importlib
from typing import Any, Callable

__all__ = ["InfillResult", "ModelSpec", "Training", "sample_names"]


@dataclasses.dataclass
class Training:
    """What ``make_training`` returns: the three pure pieces for :func:`inbetween_jax.train.run_training`
    plus the run metadata written to ``run.json`` (:func:`inbetween_jax.train.run.write_run`).

    init_fn(key) -> state;  step_fn(state, batch, key) -> (state, metrics);  batch_fn(step, key) -> batch.
    meta: ``skeleton`` (dict), ``fps``, ``stats`` (name -> array), ``data`` (provenance), ``extra``.
    """
    init_fn: Callable
    step_fn: Callable
    batch_fn: Callable
    num_steps: int
    meta: dict
    describe: str = ""       # one line for the user: what it trains on
    files: dict = dataclasses.field(default_factory=dict)   # file name -> writer(path): saved in the run folder


def sample_names(n: int) -> list:
    """``["sample_00", "sample_01", ...]`` (at least two digits): the names of ``n`` samples."""
    width = max(2, len(str(n - 1)))
    return [f"sample_{i:0{width}d}" for i in range(n)]


@dataclasses.dataclass
class InfillResult:
    """What ``infer.infill(args, run)`` returns; the CLI writes it (BVH files, previews, ``infill.json``).

    samples: ``[(name, [Motion, ...], generated)]``: one Motion per character (files ``<name>.bvh``, or
        ``<name>_A.bvh`` / ``<name>_B.bvh`` for two), ``generated`` a (T,) bool mask of the frames the model
        made (None: all but the first and last) for the previews.
    summary: JSON-able facts for ``infill.json`` (inputs, frames, checkpoint step ...).
    extra_files: ``{file name: writer(path)}`` (e.g. a ``.npy`` of predicted positions).
    what: how previews name the frames that were given (``"keyframes"``, ``"known frames"``).
    notes: one-line remarks for the user about how the inputs were read (e.g. merged gap ranges).
    """
    samples: list
    summary: dict
    extra_files: dict = dataclasses.field(default_factory=dict)
    what: str = "keyframes"
    notes: list = dataclasses.field(default_factory=list)


@dataclasses.dataclass(frozen=True)
class ModelSpec:
    """A registered model: its name, package and one-line summary; the roles are imported on first use."""
    name: str
    package: str
    summary: str

    def module(self, role: str) -> Any:
        """The model's ``config`` / ``features`` / ``model`` / ``losses`` / ``train`` / ``infer`` / ``bench`` module."""
        return importlib.import_module(f"{self.package}.{role}")

    # config (no JAX import)
    @property
    def presets(self) -> tuple:
        return tuple(self.module("config").PRESETS)

    @property
    def default_preset(self) -> str:
        return self.module("config").DEFAULT_PRESET

    def get_config(self, preset: str | None = None):
        return self.module("config").get_config(preset or self.default_preset)

    def config_class(self) -> type:
        return self.module("config").Config

    # training
    def load_data(self, cfg, source, split: str = "train"):
        return self.module("train").load_data(cfg, source, split)

    def make_training(self, cfg, data) -> Training:
        return self.module("train").make_training(cfg, data)

    # inference
    def load(self, run):
        return self.module("infer").load(run)

    @property
    def infill_options(self) -> dict:
        return dict(importlib.import_module(self.package).INFILL_OPTIONS)

    def infill(self, args, run):
        return self.module("infer").infill(args, run)

    # benchmark
    def benchmark(self, source, results_dir: str, run_dir: str | None, quick: bool = False) -> dict:
        return self.module("bench").run(source, results_dir, run_dir, quick)
