"""Where a vehicle enters the kit: :func:`resolve_vehicle` turns a named vehicle's name, a
vehicle file or a spec into one checked :class:`~dgt_lib.core.vehicle_spec.VehicleSpec`,
once, at the edge (``dgt plan --vehicle``, a notebook); the spec then flows down.

A vehicle outside the range of the vehicles the kit trains on (the four named and
:func:`~dgt_lib.core.vehicle_generator.generated_vehicles`) resolves with a
:class:`VehicleRangeWarning` naming each field outside and its range: a network has never
seen such a vehicle.

Example::

    from dgt_lib.core.vehicle_range import resolve_vehicle
    truck = resolve_vehicle("examples/my_truck.toml")
    jeep = resolve_vehicle("jeep")
"""

from __future__ import annotations

import warnings
from functools import cache
from pathlib import Path

from dgt_lib.core.vehicle_file import load_vehicle
from dgt_lib.core.vehicle_generator import generated_vehicles
from dgt_lib.core.vehicle_rules import FIELD_RULES, check_vehicle, spec_fields
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import VEHICLE_SPECS, get_vehicle

RANGE_FIELDS: tuple[str, ...] = tuple(
    name for name in FIELD_RULES if name not in ("name", "drive", "color")
    and not name.startswith("camera."))
"""The fields compared with the training vehicles' range (the camera mount is not: the
network sees BEV patches, not camera images)."""


class VehicleRangeWarning(UserWarning):
    """A vehicle with a field outside the range of the vehicles the kit trains on."""


@cache
def training_ranges() -> dict[str, tuple[float, float]]:
    """(lowest, highest) of each :data:`RANGE_FIELDS` field over the training vehicles:
    the four named ones and ``generated_vehicles()`` (12, seed 0)."""
    rows = [spec_fields(s) for s in [*VEHICLE_SPECS.values(), *generated_vehicles()]]
    return {f: (min(r[f] for r in rows), max(r[f] for r in rows)) for f in RANGE_FIELDS}


def out_of_range(spec: VehicleSpec) -> dict[str, tuple[float, float, float]]:
    """``{field: (value, lowest, highest)}`` for each field of ``spec`` outside
    :func:`training_ranges` (empty when every field is inside)."""
    values = spec_fields(spec)
    return {f: (values[f], lo, hi) for f, (lo, hi) in training_ranges().items()
            if not lo <= values[f] <= hi}


def warn_out_of_range(spec: VehicleSpec, where: str) -> None:
    """Warn (:class:`VehicleRangeWarning`, starting with ``where``) when
    :func:`out_of_range` finds a field."""
    outside = out_of_range(spec)
    if outside:
        items = "; ".join(f"{f} = {v:g} (trained on {lo:g} … {hi:g})"
                          for f, (v, lo, hi) in outside.items())
        warnings.warn(f"{where}: outside the vehicles the kit trains on: {items}",
                      VehicleRangeWarning, stacklevel=3)


def resolve_vehicle(vehicle: str | Path | VehicleSpec) -> VehicleSpec:
    """The checked spec of a named vehicle's name, a ``.toml`` vehicle file
    (:func:`~dgt_lib.core.vehicle_file.load_vehicle`) or a spec: one
    ``InvalidVehicleError`` line for an impossible spec, an ``UnknownVehicleError`` listing
    the named vehicles for any other name, a :class:`VehicleRangeWarning` for each field
    outside the training vehicles' range."""
    if isinstance(vehicle, VehicleSpec):
        spec, where = check_vehicle(vehicle), vehicle.name
    elif str(vehicle).endswith(".toml"):
        spec, where = load_vehicle(vehicle), str(vehicle)
    else:
        return get_vehicle(str(vehicle))  # a named vehicle: inside the range it defines
    warn_out_of_range(spec, where)
    return spec
