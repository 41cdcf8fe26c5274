"""A vehicle from a TOML file: :func:`load_vehicle` reads it into a
:class:`~dgt_lib.core.vehicle_spec.VehicleSpec`, checked before anything runs
(docs/vehicles.md has the format, ``examples/my_truck.toml`` an example). The four named
vehicles are such files too (:mod:`dgt_lib.core.vehicles`), read by the same function.

The file holds the ``VehicleSpec`` fields with their units in their names, angles in
degrees (``max_steer_deg``), and an optional ``[camera]`` table (``forward_m``, ``up_m``,
``pitch_down_deg``); without it the camera is mounted by
:func:`~dgt_lib.core.vehicle_rules.default_camera`. ``rolling_resistance``,
``drag_area_m2`` and ``color`` may be left out (``VehicleSpec``'s defaults). An unknown,
missing, mistyped or impossible field stops with one line naming it
(:class:`~dgt_lib.core.vehicle_rules.InvalidVehicleError`; the rules are
:mod:`dgt_lib.core.vehicle_rules`' tables). Whether the vehicle lies inside the range of
the vehicles the kit trains on is checked where a vehicle enters
(:func:`~dgt_lib.core.vehicle_range.resolve_vehicle`), not here: the named vehicles
define that range.

Example::

    from dgt_lib.core.vehicle_file import load_vehicle
    truck = load_vehicle("examples/my_truck.toml")
    truck.max_climb_deg
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

from dgt_lib.core.vehicle_rules import (
    CAMERA_FIELDS,
    OPTIONAL_FIELDS,
    InvalidVehicleError,
    check_fields,
    default_camera,
    fields_to_spec,
    spec_fields,
)
from dgt_lib.core.vehicle_spec import VehicleSpec


def _flatten(data: Mapping[str, object], where: str) -> dict[str, object]:
    """The file's tables → flat fields (``camera.forward_m`` …), defaults filled in."""
    flat = {k: v for k, v in data.items() if k != "camera"}
    camera = data.get("camera")
    if camera is not None:
        if not isinstance(camera, Mapping):
            raise InvalidVehicleError(f"{where}: camera = {camera!r} has the wrong type: "
                                      f"camera must be a table ({', '.join(CAMERA_FIELDS)})")
        flat.update({f"camera.{k}": v for k, v in camera.items()})
    for name, value in OPTIONAL_FIELDS.items():
        flat.setdefault(name, value)
    geometry = ("length_m", "height_m", "ground_clearance_m", "wheel_radius_m")
    if camera is None and all(isinstance(flat.get(g), (int, float))
                              and not isinstance(flat.get(g), bool) for g in geometry):
        mount = default_camera(*(float(flat[g]) for g in geometry))
        flat.update({"camera.forward_m": mount.forward_m, "camera.up_m": mount.up_m,
                     "camera.pitch_down_deg": math.degrees(mount.pitch_down_rad)})
    return flat


def parse_vehicle(data: Mapping[str, object], where: str = "vehicle") -> VehicleSpec:
    """A checked :class:`VehicleSpec` from a file's parsed TOML ``data``; ``where``
    names the file in messages."""
    return fields_to_spec(check_fields(_flatten(data, where), where))


def _toml_reader():
    """``tomllib`` (Python ≥ 3.11), else the ``tomli`` package it came from."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        try:
            import tomli as tomllib
        except ModuleNotFoundError:
            raise InvalidVehicleError("reading a vehicle file needs Python ≥ 3.11 (tomllib) "
                                      "or the tomli package") from None
    return tomllib


def load_vehicle(path: str | Path) -> VehicleSpec:
    """The vehicle of the TOML file ``path`` (see the module docstring), or
    :class:`~dgt_lib.core.vehicle_rules.InvalidVehicleError` naming the file and field."""
    path = Path(path)
    toml = _toml_reader()
    try:
        data = toml.loads(path.read_text(encoding="utf-8"))
    except toml.TOMLDecodeError as e:
        raise InvalidVehicleError(f"{path}: not valid TOML: {e}") from None
    except OSError as e:
        raise InvalidVehicleError(f"{path}: cannot read it: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise InvalidVehicleError(f"{path}: not UTF-8 text (byte {e.start}): a vehicle file "
                                  "is TOML, which is UTF-8") from None
    return parse_vehicle(data, str(path))


def _toml_value(value: object) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml_value(x) for x in value) + "]"
    return repr(float(value))


def vehicle_toml(spec: VehicleSpec) -> str:
    """``spec`` as the text of a vehicle file. :func:`load_vehicle` reads it back; the
    angles pass through degrees, so a read-back angle may differ in its last bit (the
    named vehicles' read back exactly)."""
    fields = spec_fields(spec)
    top = [f"{k} = {_toml_value(v)}" for k, v in fields.items() if not k.startswith("camera.")]
    cam = [f"{k.removeprefix('camera.')} = {_toml_value(v)}" for k, v in fields.items()
           if k.startswith("camera.")]
    return "\n".join([*top, "", "[camera]", *cam]) + "\n"
