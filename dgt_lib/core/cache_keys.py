"""What a cache key reads of a configuration (docs/ARCHITECTURE.md → Artifacts).

A stage's artifact is keyed by the settings it depends on plus the stage's version (a
``format`` or ``*_version`` number beside the stage, bumped by any change that alters its
results). A settings object (a dataclass) enters the key by the fields that differ from
their defaults, and not at all while every field has its default. So

- a new setting whose default computes exactly as before leaves every stored key valid,
  and so does deleting a setting no stored run changed;
- changing a default alters results: the versions of the stages it feeds are bumped (and
  ``tests/test_cache_keys.py`` compares every default with its committed snapshot).

Keys stored before this rule held every field: :func:`legacy_form` reads such a stored
key in today's form, so those artifacts stay valid when they were built with today's
settings.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
from pathlib import Path
from typing import Any

import numpy as np

KEY_FORM = 2
"""The form of the keys :func:`jsonable` gives; metadata written before it has none."""

REMOVED_DEFAULTS: dict[str, object] = {
    "turn_around_after_stall": False, "turn_around_min_m": 5.0,  # CollectConfig
    "weight_decay": 0.0, "label_weighting": "none", "label_bins": 5,  # TrainConfig
    "max_label_weight": 10.0,
    "safety_margin_m": 0.0,  # PlannerConfig
    "mppi_batch_size": 1000,  # ExperimentsConfig: now mppi.batch_size
    "first_step_weight": 0.0, "corner_accel_mps2": 0.0,  # MPPIConfig
    "steer_tau_s": 2.0, "steer_sigma": 0.3, "edge_margin_m": 15.0,  # CollectConfig
    "tree_lookahead_m": 10.0, "spawn_margin_m": 10.0, "spawn_max_slope_deg": 15.0,
    "max_angular_rate_dps": 100.0, "shot_distance_m": 20.0,  # the last: PlannerConfig
}
"""Deleted settings, with the value every stored run used: :func:`legacy_form` leaves them
out wherever a key stored in the older form has them and today's key does not (a stage
that keeps a deleted setting's value as a constant under its old name compares it)."""

_TYPES: dict[str, type] = {}
"""Settings classes by name, as met by :func:`jsonable` (what :func:`legacy_form` reads)."""


@functools.cache
def defaults(cls: type) -> dict[str, Any]:
    """The default of each field of dataclass ``cls`` that has one."""
    out = {}
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            out[f.name] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            out[f.name] = f.default_factory()
    return out


def _untouched(value: Any) -> bool:
    """A settings object with every field at its default, in key form."""
    return isinstance(value, dict) and set(value) == {"__type__"}


def jsonable(obj: Any, memo: dict[int, Any] | None = None) -> Any:
    """``obj`` in key form, as plain JSON values: a dataclass tagged with its type and
    holding the fields that differ from their defaults, an array by its SHA-256, a dict
    without the settings objects left untouched. ``memo`` maps ``id`` of a dataclass
    already converted in this call to its value: a configuration that repeats one settings
    object (1,300 episodes of one profile) converts it once."""
    memo = {} if memo is None else memo
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        if id(obj) not in memo:
            cls = type(obj)
            _TYPES[cls.__name__] = cls
            base = defaults(cls)
            fields = {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}
            changed = {k: v for k, v in dataclasses.asdict(obj).items()
                       if k not in base or not _equal(fields[k], base[k])}
            memo[id(obj)] = {"__type__": cls.__name__, **jsonable(changed, memo)}
        return memo[id(obj)]
    if isinstance(obj, dict):
        items = {str(k): jsonable(v, memo)
                 for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
        return {k: v for k, v in items.items() if not _untouched(v)}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v, memo) for v in obj]
    if isinstance(obj, np.ndarray):
        return {"__array__": hashlib.sha256(np.ascontiguousarray(obj).tobytes()).hexdigest(),
                "shape": list(obj.shape), "dtype": str(obj.dtype)}
    if isinstance(obj, (np.integer, np.floating, np.bool_)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, (str, int, float, bool)):
        return obj
    raise TypeError(f"cannot hash configuration value of type {type(obj).__name__}: {obj!r}")


def _equal(a: Any, b: Any) -> bool:
    """Whether two setting values are the same in key form."""
    return jsonable(a) == jsonable(b)


def legacy_form(stored: Any, current: Any) -> Any:
    """A key stored before :data:`KEY_FORM` (every field of every settings object), read
    in today's form for comparison with ``current`` (today's key, in key form): fields at
    today's defaults, and :data:`REMOVED_DEFAULTS` at theirs where ``current`` does not
    name them, left out; a stage version that did not exist then (``format`` 1 today)
    taken as 1."""
    out = _strip_defaults(stored, current)
    if (isinstance(out, dict) and isinstance(current, dict)
            and current.get("format") == 1 and "format" not in out):
        out["format"] = 1
    return out


def _strip_defaults(value: Any, current: Any) -> Any:
    """:func:`legacy_form` without the stage version; ``current`` is today's key at the same
    place. A settings object inside another was stored as a plain dict
    (``dataclasses.asdict``), so defaults are compared in that form."""
    if isinstance(value, list):
        now = current if isinstance(current, list) and len(current) == len(value) else None
        return [_strip_defaults(v, now[i] if now else None) for i, v in enumerate(value)]
    if not isinstance(value, dict) or "__array__" in value:
        return value
    now = current if isinstance(current, dict) else {}
    base = {k: v for k, v in REMOVED_DEFAULTS.items() if k not in now}
    if value.get("__type__") in _TYPES:
        base.update({k: jsonable(dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v)
                     for k, v in defaults(_TYPES[value["__type__"]]).items()})
    out = {k: _strip_defaults(v, now.get(k)) for k, v in value.items()
           if k not in base or v != base[k]}
    return {k: v for k, v in out.items() if not _untouched(v)}
