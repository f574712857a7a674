"""Trained weights that ship inside the package: ``inbetween_jax/assets/weights/<model>/``.

Each folder is a *shipped run*: ``run.json`` (the training run's description plus a ``shipped`` record: step,
dtype, kept key paths and where the weights came from) and ``params.npz`` (the inference parameters only, flat
'/'-joined key paths, float16 by default).  :func:`inbetween_jax.train.run.load_run` reads such a folder and
:func:`inbetween_jax.train.run.restore_state` restores it into the model's full train-state structure (the
dropped parts -- optimizer state, discriminators -- come back as zeros), so every ``infer.load(run)`` works
unchanged::

    run = shipped_run("scvae")                       # None when no weights ship for scvae
    trained = REGISTRY["scvae"].module("infer").load(run)

Writing them: ``inbetween ship-weights RUN_DIR [--step N] [--dtype float16|float32]``
(:func:`export_run`).  ``$INBETWEEN_WEIGHTS_DIR`` replaces the package folder (tests, private weights).
"""
from __future__ import annotations

import datetime
import json
import os

import numpy as np

from inbetween_jax.train.run import RUN_FILE, WEIGHTS_FILE, Run, RunError, flat_leaves, load_run

__all__ = ["ENV", "INFERENCE_SWITCHES", "KEEP", "EXACT", "weights_root", "shipped_dir", "shipped_run",
           "shipped_as_trained", "inference_state", "export_run", "folder_bytes", "config_with_overrides"]

ENV = "INBETWEEN_WEIGHTS_DIR"
# Switches that only change inference (the trained parameters are the same either way): ``export_run(inference=)``.
INFERENCE_SWITCHES = {"interaction": ("model.refiner", "model.latent_scale", "model.bank_k", "model.bank_weight",
                                      "model.texture_sigma", "model.texture_gain", "model.bank_guessed", "model.ease_frames",
                                      "model.ood_gate", "model.bank_sample_weight", "model.bank_pair_weight",
                                      "model.bank_sample_gated", "model.departure_cap"),
                      "scvae": ("model.search", "model.bank_k", "model.bank_weight", "model.bank_tau", "model.ood_gate",
                                "model.motion_temperature", "model.motion_spread", "model.bank_sample_weight",
                                "model.bank_sample_gated", "model.context_base", "model.context_damping",
                                "model.context_max_turn", "model.context_max_step", "model.timing_spread",
                                "model.timing_parts", "model.timing_spread_in_clip", "model.timing_spread_fallback"),
                      "cae": ("model.mirror_average", "model.ood_gate", "model.net_edge_fade", "model.base_edge_fade",
                              "model.root_bound", "model.root_edge_fade", "model.match_k", "model.match_lo",
                              "model.match_hi", "model.match_disp", "model.match_departure", "model.match_speed_scale",
                              "model.global_base_near", "model.global_base_far", "model.global_base_fade")}
# Per model: the key-path prefixes of the train state that ``infer.load`` / inference use.
KEEP = {"scvae": ("params", "stats"),                # generators + normalisation (disc, opt_g, opt_d dropped)
        "cae": ("params",),                          # opt_state dropped
        "interaction": ("params/gen", "params/ref")}  # pae / disc (training losses only) and opt dropped
# Key-path prefixes always stored as float32 (normalisation statistics).
EXACT = ("stats",)
DTYPES = ("float16", "float32")


def weights_root(root: str | None = None) -> str:
    """``root``, else ``$INBETWEEN_WEIGHTS_DIR``, else the package's ``assets/weights`` folder."""
    return root or os.environ.get(ENV) or os.path.join(os.path.dirname(__file__), "assets", "weights")


def shipped_dir(model: str, root: str | None = None) -> str | None:
    """The shipped-run folder of ``model`` (``<root>/<model>``) when it holds weights, else None."""
    d = os.path.join(weights_root(root), model)
    return d if os.path.isfile(os.path.join(d, RUN_FILE)) and os.path.isfile(os.path.join(d, WEIGHTS_FILE)) else None


def shipped_run(model: str, root: str | None = None) -> Run | None:
    """The shipped :class:`~inbetween_jax.train.run.Run` of ``model``, or None when none ships.

    Raises:
        RunError: the folder exists but is unusable (one line), or holds another model's weights.
    """
    d = shipped_dir(model, root)
    if d is None:
        return None
    run = load_run(d)
    if run.model != model or run.weights is None:
        raise RunError(f"{d}: holds {run.model} weights, not {model}" if run.model != model
                       else f"{d}: not a shipped run (no 'shipped' record in {RUN_FILE})")
    return run


def shipped_as_trained(model: str, root: str | None = None) -> Run | None:
    """:func:`shipped_run` with the config its network was trained with: the recorded preset and training
    overrides rebuilt, so the inference-only switches set at export (:data:`INFERENCE_SWITCHES`) are off -- the
    network's own validation score, the time-to-quality target (``experiments/time_to_quality.py``)."""
    import dataclasses

    from inbetween_jax.runner import build_config
    from inbetween_jax.train.config import config_to_dict
    run = shipped_run(model, root)
    if run is None:
        return None
    return dataclasses.replace(run, config=config_to_dict(build_config(model, run.preset, run.overrides)))


def _under(path: str, prefixes) -> bool:
    return any(path == p or path.startswith(p + "/") for p in prefixes)


def inference_state(state, model: str, dtype: str = "float16") -> dict:
    """``{key path: array}`` of the leaves of a restored train ``state`` that inference uses (:data:`KEEP`);
    floating arrays cast to ``dtype`` except the :data:`EXACT` ones (float32)."""
    if model not in KEEP:
        raise RunError(f"no inference key list for model {model!r} (known: {', '.join(KEEP)})")
    out = {}
    for name, leaf in flat_leaves(state).items():
        if not _under(name, KEEP[model]):
            continue
        a = np.asarray(leaf)
        if np.issubdtype(a.dtype, np.floating):
            a = a.astype(np.float32 if _under(name, EXACT) else dtype)
        out[name] = a
    if not out:
        raise RunError(f"the {model} state holds none of {', '.join(KEEP[model])}")
    return out


def folder_bytes(path: str) -> int:
    """Total size of the files under ``path``."""
    return sum(os.path.getsize(os.path.join(d, f)) for d, _, files in os.walk(path) for f in files)


def _restore_full(run: Run) -> dict:
    """The state a checkpointed run's ``infer.load`` restores: the S-CVAE's full train state (``Trained.state``),
    ``{"params": ...}`` for the others (their loaded objects keep only the parameters)."""
    import jax

    from inbetween_jax.models import REGISTRY
    trained = REGISTRY[run.model].module("infer").load(run)
    state = getattr(trained, "state", None)
    return jax.device_get(state if isinstance(state, dict) else {"params": trained.params})


def export_run(run_dir: str, step: int | None = None, out_dir: str | None = None, dtype: str = "float16",
               why: str | None = None, root: str | None = None, inference: tuple = ()) -> dict:
    """Write the shipped run of ``run_dir``'s checkpoint ``step`` (default: the latest) to ``out_dir``
    (default ``<weights_root(root)>/<model>``): ``run.json`` + ``params.npz``.

    why: how the step was chosen (recorded; default "latest checkpoint" / "chosen step").
    inference: ``key=value`` overrides of inference-only switches (:data:`INFERENCE_SWITCHES`, e.g.
    ``model.refiner=false``) written into the shipped ``run.json``'s config and recorded under ``shipped``.
    Returns ``{"out_dir", "model", "step", "dtype", "bytes", "arrays", "parameters", "checkpoint_bytes"}``.

    Raises:
        RunError: not a run folder, no such step, unknown dtype, or a model without a key list (one line).
    """
    if dtype not in DTYPES:
        raise RunError(f"--dtype {dtype}: choose {' or '.join(DTYPES)}")
    run = load_run(run_dir, step)
    if run.weights is not None:
        raise RunError(f"{run_dir}: already a shipped run (export from the training run folder)")
    if run.model not in KEEP:
        raise RunError(f"{run_dir}: no inference key list for model {run.model!r} (known: {', '.join(KEEP)})")
    bad = [o for o in inference if o.split("=", 1)[0] not in INFERENCE_SWITCHES.get(run.model, ())]
    if bad:
        raise RunError(f"--set {bad[0]}: not an inference switch of {run.model} "
                       f"(choose {', '.join(INFERENCE_SWITCHES.get(run.model, ())) or 'none'})")
    arrays = inference_state(_restore_full(run), run.model, dtype)
    out_dir = out_dir or os.path.join(weights_root(root), run.model)
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(run_dir, RUN_FILE)) as f:
        meta = json.load(f)
    if inference:
        meta["config"] = config_with_overrides(run.model, meta["config"], inference)
    trained = max([int(h.get("steps", 0)) for h in meta.get("history", [])] + [int(run.step)])
    meta["shipped"] = {
        "step": int(run.step), "dtype": dtype, "keep": list(KEEP[run.model]),
        "why": why or ("latest checkpoint" if step is None else f"chosen step {step}"),
        "from_run": os.path.basename(os.path.normpath(run_dir)),
        "data_source": run.data.get("source"), "steps_trained": trained, "inference": list(inference),
        "parameters": int(sum(a.size for a in arrays.values())),
        "exported": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    for name in ("ood.npz", "ood_calibration.json"):   # the out-of-distribution gate (models/ood.py), if calibrated
        if os.path.exists(os.path.join(run_dir, name)):
            import shutil
            shutil.copyfile(os.path.join(run_dir, name), os.path.join(out_dir, name + ".tmp"))
            os.replace(os.path.join(out_dir, name + ".tmp"), os.path.join(out_dir, name))
    tmp = os.path.join(out_dir, WEIGHTS_FILE + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, os.path.join(out_dir, WEIGHTS_FILE))
    with open(os.path.join(out_dir, RUN_FILE + ".tmp"), "w") as f:
        json.dump(meta, f, indent=1)
    os.replace(os.path.join(out_dir, RUN_FILE + ".tmp"), os.path.join(out_dir, RUN_FILE))
    return {"out_dir": out_dir, "model": run.model, "step": int(run.step), "dtype": dtype,
            "bytes": folder_bytes(out_dir), "arrays": len(arrays), "parameters": meta["shipped"]["parameters"],
            "checkpoint_bytes": folder_bytes(os.path.join(run.checkpoint_dir, str(run.step)))}


def config_with_overrides(model: str, config: dict, overrides) -> dict:
    """A run's config dict with ``key=value`` overrides applied (and checked) through the model's Config (keys
    the run predates take the Config's defaults).

    Raises:
        RunError: an unknown key or a bad value (one line).
    """
    from inbetween_jax.models import get_spec
    from inbetween_jax.train.config import ConfigError, apply_overrides, config_from_dict, config_to_dict
    spec = get_spec(model)
    try:
        cfg = config_from_dict(type(spec.get_config(spec.default_preset)), config)
        return config_to_dict(apply_overrides(cfg, list(overrides)))
    except (ConfigError, TypeError, ValueError) as e:
        raise RunError(f"--set {' '.join(overrides)}: {e}") from None
