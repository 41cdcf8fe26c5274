"""What a cache key reads of a configuration (docs/ARCHITECTURE.md → Artifacts).

A stage's artifact is keyed by the settings it depends on plus the stage's version (a
``format`` or ``*_version`` number beside the stage, bumped by any change that alters its
results). A settings object (a dataclass) enters the key by the fields that differ from
their defaults, and not at all while every field has its default. So

- a new setting whose default computes exactly as before leaves every stored key valid,
  and so does deleting a setting no stored run changed;
- changing a default alters results: the versions of the stages it feeds are bumped (and
  ``tests/test_cache_keys.py`` compares every default with its committed snapshot).

Keys stored before this rule held every field (metadata without ``key_form``): their
artifacts are rebuilt once, and the rebuild says why.
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
