"""Settings changed without editing code: ``dgt reproduce --set planner.beta=50`` and
:meth:`~dgt_lib.core.config.Profile.with_overrides` (docs/ARCHITECTURE.md → Profiles).

A name is ``section.field`` of a :class:`~dgt_lib.core.config.Profile` section or one of
:data:`TOP_LEVEL_SETTINGS`; a value is converted to the field's annotated type and checked,
with an error that names the valid fields or the type expected.
"""

from __future__ import annotations

import math
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import fields, is_dataclass, replace
from functools import cache

TOP_LEVEL_SETTINGS: tuple[str, ...] = ("seed", "seeds", "workers")
"""The :class:`Profile` fields that are settings of their own (not a section's)."""


@cache
def _schema(profile_type: type) -> tuple[dict[str, object], tuple[str, ...]]:
    """The annotations of a :class:`Profile` class and its sections ``--set`` can change,
    one per pipeline stage: worlds, collect, bev, train, costmap, planner, experiments, mppi,
    ground_truth, conditioned. (``execution`` — where jobs run, not what they compute — is set by
    ``--executor``, ``--address`` and ``--device``.) The class comes from the profile being
    changed, so this module needs no import of :mod:`dgt_lib.core.config`."""
    types_ = typing.get_type_hints(profile_type)
    sections = tuple(f.name for f in fields(profile_type)
                     if is_dataclass(types_[f.name]) and f.compare)
    return types_, sections


class InvalidOverrideError(ValueError):
    """An override with an unknown name, or a value that does not fit its field's type."""


def setting_names(profile_type: type, section: str | None = None) -> list[str]:
    """The valid dotted names of ``profile_type``: every ``section.field`` and
    :data:`TOP_LEVEL_SETTINGS`, or one section's ``section.field`` names."""
    types_, sections = _schema(profile_type)
    chosen = sections if section is None else (section,)
    names = [f"{s}.{f.name}" for s in chosen for f in fields(types_[s])]
    return names + list(TOP_LEVEL_SETTINGS) if section is None else names


def setting_type(profile_type: type, key: str) -> tuple[str | None, str, object]:
    """``"planner.beta"`` → ``("planner", "beta", float)``: the section (None for a
    top-level setting), the field and its annotation in ``profile_type``. Raises
    :class:`InvalidOverrideError` listing the valid names for an unknown one."""
    types_, sections = _schema(profile_type)
    section, dot, name = key.strip().rpartition(".")
    if not dot and name in TOP_LEVEL_SETTINGS:
        return None, name, types_[name]
    if not dot or section not in sections:
        raise InvalidOverrideError(
            f"unknown setting {key!r}: a setting is SECTION.FIELD, SECTION one of "
            f"{', '.join(sections)}, or one of {', '.join(TOP_LEVEL_SETTINGS)}")
    hints = typing.get_type_hints(types_[section])
    if name not in hints:
        valid = ", ".join(f"{section}.{f.name}" for f in fields(types_[section]))
        raise InvalidOverrideError(f"unknown setting {key!r}; valid {section} settings: {valid}")
    return section, name, hints[name]


def _current(profile: object, section: str | None, name: str) -> object:
    """The profile's value of a setting (the example in an error message)."""
    return getattr(profile if section is None else getattr(profile, section), name)


def format_setting(value: object) -> str:
    """A value as it is typed on the command line: ``50.0``, ``true``, ``4,2``, ``none``."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        return ",".join(format_setting(v) for v in value)
    return str(value)


P = typing.TypeVar("P")
"""A :class:`~dgt_lib.core.config.Profile` (its class is read from the instance)."""

_TRUE, _FALSE = ("true", "yes", "on", "1"), ("false", "no", "off", "0")
_TYPE_WORDS = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}


def _scalar(value: object, hint: type) -> object:
    """``value`` (a command-line string or a Python value) as ``hint``; ValueError if it
    does not fit (a bool is not a number, 2.5 is not an integer)."""
    if hint is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.strip().lower() in _TRUE + _FALSE:
            return value.strip().lower() in _TRUE
    elif hint is int:
        if isinstance(value, str):
            return int(value.strip())
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif hint is float:
        number = float(value.strip()) if isinstance(value, str) else value
        if (isinstance(number, (int, float)) and not isinstance(number, bool)
                and not math.isnan(number)):
            return float(number)
    elif hint is str and isinstance(value, str):
        return value.strip()
    raise ValueError(value)


def _expected(hint: object) -> str:
    """Words for a type: ``"2 integers separated by commas"``, ``"a number or none"``."""
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return " or ".join(_expected(a) if a is not type(None) else "none" for a in args)
    if typing.get_origin(hint) is tuple:
        word = _TYPE_WORDS[args[0]].split(" ", 1)[1]  # "an integer" → "integer"
        count = "any number of" if args[-1] is Ellipsis else str(len(args))
        return f"{count} {word}s separated by commas"
    return _TYPE_WORDS.get(hint, getattr(hint, "__name__", str(hint)))


def _convert(value: object, hint: object) -> object:
    """``value`` as the annotation ``hint`` (bool, int, float, str, ``X | None``, tuples
    of those); ValueError if it does not fit."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None or (isinstance(value, str) and value.strip().lower() == "none"):
            if type(None) in args:
                return None
            raise ValueError(value)
        for arg in (a for a in args if a is not type(None)):
            try:
                return _convert(value, arg)
            except ValueError:
                pass
        raise ValueError(value)
    if origin is tuple:
        items = value.split(",") if isinstance(value, str) else value
        if not isinstance(items, (list, tuple)):
            raise ValueError(value)
        types_ = [args[0]] * len(items) if args[-1] is Ellipsis else list(args)
        if len(items) != len(types_):
            raise ValueError(value)
        return tuple(_scalar(v, t) for v, t in zip(items, types_, strict=True))
    return _scalar(value, hint)


def coerce_setting(key: str, value: object, hint: object, *, example: object = None) -> object:
    """``value`` converted to the annotation ``hint`` of setting ``key``; raises
    :class:`InvalidOverrideError` saying what was expected (with ``example``, the current
    value, as it would be typed)."""
    try:
        return _convert(value, hint)
    except (ValueError, TypeError):
        hint_text = "" if example is None else f" (e.g. {key}={format_setting(example)})"
        raise InvalidOverrideError(f"{key} expects {_expected(hint)}{hint_text}, "
                                   f"got {value!r}") from None


def parse_overrides(items: Iterable[str]) -> dict[str, str]:
    """``["planner.beta=50", "experiments.n_hill=10"]`` → ``{"planner.beta": "50", …}``
    (the command line's ``--set``; a later item wins). Names and values are checked by
    :meth:`Profile.with_overrides`."""
    out: dict[str, str] = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise InvalidOverrideError(f"a setting is NAME=VALUE (e.g. planner.beta=50), "
                                       f"got {item!r}")
        out[key.strip()] = value
    return out


def apply_overrides(profile: P, overrides: Mapping[str, object]) -> P:
    """``profile`` with ``overrides`` applied (see :meth:`Profile.with_overrides`); the
    changed settings are recorded in ``Profile.overrides``. The profile is made once, with
    every override in, so its range and cross-field checks
    (:mod:`dgt_lib.core.constraints`) see the settings together."""
    top: dict[str, object] = {}
    changed: dict[str, dict[str, object]] = {}
    recorded = dict(profile.overrides)
    for key, raw in overrides.items():
        section, name, hint = setting_type(type(profile), key)
        value = coerce_setting(key, raw, hint, example=_current(profile, section, name))
        if section is None:
            top[name] = value
        else:
            changed.setdefault(section, {})[name] = value
        recorded[key.strip()] = value
    # Each section is made once, with all its changes: its own checks (core/constraints.py,
    # an InvalidSettingError naming the settings) see them together, in any order.
    sections = {s: replace(getattr(profile, s), **values) for s, values in changed.items()}
    return replace(profile, **top, **sections, overrides=tuple(recorded.items()))


def _type_text(hint: object) -> str:
    """A setting's annotation as it reads in the code: ``float``, ``int | None``,
    ``tuple[int, int]``."""
    return hint.__name__ if isinstance(hint, type) else str(hint)


def settings_table(profile: object) -> list[tuple[str, str, str]]:
    """Every name ``--set`` accepts, its type and the profile's value as it would be
    typed: ``("planner.beta", "float", "150.0")``, read from the Profile's dataclasses
    (:func:`setting_names`), so it lists exactly what ``--set``
    checks against."""
    rows = []
    for name in setting_names(type(profile)):
        section, field_name, hint = setting_type(type(profile), name)
        owner = profile if section is None else getattr(profile, section)
        rows.append((name, _type_text(hint), format_setting(getattr(owner, field_name))))
    return rows
