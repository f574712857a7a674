"""Plain-Python experiment configs and command-line overrides.

Configs are frozen ``dataclasses`` (possibly nested) or nested ``dict``s -- no ``ml_collections``.
Overrides are ``"dotted.key=value"`` strings; each value is parsed with the type of the field it
replaces, so a typo or a badly typed value fails early with a one-line :class:`ConfigError`::

    cfg = apply_overrides(cfg, ["model.latent_dim=64", "lr=1e-3", "use_ema=false", "dims=128,128"])
    json.dumps(config_to_dict(cfg))   # for logging / checkpoints
"""

from __future__ import annotations

import ast
import dataclasses
import difflib
from typing import Any, Mapping, Sequence

__all__ = ["ConfigError", "TrainConfig", "apply_overrides", "config_from_dict", "config_to_dict", "describe_config",
           "parse_value"]

_TRUE = {"true", "t", "yes", "y", "on", "1"}
_FALSE = {"false", "f", "no", "n", "off", "0"}
_NONE = {"none", "null"}


class ConfigError(ValueError):
    """Raised for an unknown key or an unparsable value; the message is one line naming the key."""


def _is_node(obj: Any) -> bool:
    """True for containers that overrides descend into (dataclass instances and mappings)."""
    return (dataclasses.is_dataclass(obj) and not isinstance(obj, type)) or isinstance(obj, Mapping)


def _keys(node: Any) -> list[str]:
    if isinstance(node, Mapping):
        return [str(k) for k in node]
    return [f.name for f in dataclasses.fields(node)]


def _get(node: Any, key: str, full_key: str) -> Any:
    keys = _keys(node)
    if key not in keys:
        close = difflib.get_close_matches(key, keys, n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        raise ConfigError(f"unknown config key '{full_key}'{hint}; valid keys here: {sorted(keys)}")
    return node[key] if isinstance(node, Mapping) else getattr(node, key)


def _set(node: Any, key: str, value: Any) -> Any:
    """Return a copy of ``node`` with ``key`` replaced (dataclasses via ``dataclasses.replace``)."""
    if isinstance(node, Mapping):
        out = dict(node)
        out[key] = value
        return out
    return dataclasses.replace(node, **{key: value})


def parse_value(text: str, existing: Any, key: str = "?") -> Any:
    """Parse the string ``text`` with the type of ``existing``.

    Rules: ``bool`` accepts true/false/yes/no/on/off/1/0 (any case); ``int`` must be an integer literal
    (``"1e3"`` is rejected); ``float`` accepts any float literal; ``str`` is taken verbatim; ``tuple``/``list``
    accept ``"1,2,3"``, ``"(1, 2)"`` or ``"[1, 2]"`` (``""`` or ``"()"`` is empty) with each element parsed with
    the type of the existing first element; when the existing value is ``None`` the text is parsed as a Python
    literal (``none``/``null`` -> None) and falls back to the plain string.

    Raises:
        ConfigError: if the text does not parse as that type (message names ``key``).
    """
    raw = text.strip()
    low = raw.lower()
    try:
        if existing is None:
            if low in _NONE:
                return None
            try:
                return ast.literal_eval(raw)
            except (ValueError, SyntaxError):
                return raw
        if isinstance(existing, bool):
            if low in _TRUE:
                return True
            if low in _FALSE:
                return False
            raise ValueError
        if isinstance(existing, int):
            return int(raw)
        if isinstance(existing, float):
            return float(raw)
        if isinstance(existing, str):
            return text
        if isinstance(existing, (tuple, list)):
            inner = raw[1:-1] if raw[:1] + raw[-1:] in ("()", "[]") else raw
            parts = [p for p in (s.strip() for s in inner.split(",")) if p != ""]
            proto = existing[0] if len(existing) else None
            items = [parse_value(p, proto, key) for p in parts]
            return type(existing)(items)
    except ConfigError:
        raise
    except (ValueError, TypeError):
        pass
    else:
        raise ConfigError(f"config key '{key}' holds an unsupported type {type(existing).__name__}")
    raise ConfigError(f"bad value for config key '{key}': expected {type(existing).__name__}, got {text!r}")


def _override(node: Any, path: Sequence[str], text: str, full_key: str) -> Any:
    current = _get(node, path[0], full_key)
    if len(path) == 1:
        if _is_node(current):
            raise ConfigError(f"config key '{full_key}' is a group, not a value; set one of {_keys(current)}")
        return _set(node, path[0], parse_value(text, current, full_key))
    if not _is_node(current):
        raise ConfigError(f"unknown config key '{full_key}': '{path[0]}' is a value, not a group")
    return _set(node, path[0], _override(current, path[1:], text, full_key))


def apply_overrides(config: Any, overrides: Sequence[str]) -> Any:
    """Return a copy of ``config`` with ``["a.b=3", "lr=1e-3", "flag=false"]`` applied in order.

    Args:
        config: frozen dataclass or (nested) dict; it is never modified in place.
        overrides: ``"dotted.key=value"`` strings (values may themselves contain ``=``).
    Returns:
        A new config of the same structure.
    Raises:
        ConfigError: (one line, naming the key) on a malformed override, unknown key or bad value.
    """
    for item in overrides:
        if "=" not in item:
            raise ConfigError(f"override {item!r} is not of the form key=value")
        key, text = item.split("=", 1)
        key = key.strip()
        if not key or any(p == "" for p in key.split(".")):
            raise ConfigError(f"override {item!r} has an empty key")
        config = _override(config, key.split("."), text, key)
    return config


def config_to_dict(config: Any) -> Any:
    """JSON-serialisable nested dict of a config (tuples become lists, unknown objects ``str``)."""
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        return {f.name: config_to_dict(getattr(config, f.name)) for f in dataclasses.fields(config)}
    if isinstance(config, Mapping):
        return {str(k): config_to_dict(v) for k, v in config.items()}
    if isinstance(config, (list, tuple)):
        return [config_to_dict(v) for v in config]
    if config is None or isinstance(config, (bool, int, float, str)):
        return config
    if hasattr(config, "item") and getattr(config, "shape", None) == ():
        return config.item()  # numpy / jax scalar
    return str(config)


# ----------------------------------------------------------------------------- the one config schema
@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """The ``train`` group, identical for every model (``Config(model, data, loss, train)``).

    The optimiser is Adam (AdamW when ``weight_decay > 0``) behind a global-norm clip when ``grad_clip > 0``;
    ``lr_schedule`` is ``constant`` or ``cosine`` (decays to ``lr * lr_final`` at ``num_steps``, after
    ``warmup_steps`` of linear warm-up).  See :func:`inbetween_jax.train.optim.make_optimizer`.
    """
    num_steps: int = 1000
    batch_size: int = 32
    lr: float = 1e-3
    b1: float = 0.9
    b2: float = 0.999
    weight_decay: float = 0.0
    grad_clip: float = 0.0          # 0: off
    lr_schedule: str = "constant"   # constant | cosine
    lr_final: float = 0.1           # cosine: final lr as a fraction of lr
    warmup_steps: int = 0
    log_every: int = 50
    ckpt_every: int = 500
    seed: int = 0
    split: str = "train"            # data split trained on; "fit" / "fit-subjects" hold validation files /
                                    # whole subjects out (checkpoint selection on them)
    keep_checkpoints: int = 3       # checkpoints kept on disk (0: all, for selection on the validation split)
    ema_decay: float = 0.0          # > 0: keep a moving average of the parameters (e.g. 0.999; optim.with_ema)
    ema_eval: bool = True           # inference (selection, bench, infill) reads that average when there is one


def config_from_dict(cls: type, data: Mapping | None) -> Any:
    """Rebuild the (nested) dataclass ``cls`` from :func:`config_to_dict` output (lists become tuples).

    Unknown keys raise :class:`ConfigError` (one line naming the key); missing keys take the defaults.
    """
    data = dict(data or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(f"unknown config key(s) {unknown} for {cls.__name__}")
    kwargs = {}
    for name, value in data.items():
        default = getattr(cls(), name)
        if dataclasses.is_dataclass(default):
            kwargs[name] = config_from_dict(type(default), value)
        elif isinstance(value, list):
            kwargs[name] = tuple(value)
        else:
            kwargs[name] = value
    return cls(**kwargs)


def describe_config(config: Any, prefix: str = "") -> list[str]:
    """``["model.latent_dim = 16", ...]``: every overridable key with its value, for ``--help`` texts."""
    lines = []
    for key in _keys(config):
        value = config[key] if isinstance(config, Mapping) else getattr(config, key)
        if _is_node(value):
            lines += describe_config(value, f"{prefix}{key}.")
        else:
            shown = ",".join(str(v) for v in value) if isinstance(value, (tuple, list)) else value
            lines.append(f"{prefix}{key} = {shown}")
    return lines
