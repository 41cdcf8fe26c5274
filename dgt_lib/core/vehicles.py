"""The four vehicles of the paper (Data Collection), read from the vehicle files shipped in
``dgt_lib/core/named_vehicles/`` by the loader that reads a user's file
(:func:`~dgt_lib.core.vehicle_file.load_vehicle`).

``jeep``, ``vw_van``, ``mercedes_van``, ``carla_cola`` (head order, docs/ARCHITECTURE.md).
Geometry is close to the real vehicles CARLA models — a Jeep Wrangler, a VW T2
van, a long Mercedes Sprinter and CARLA's "Carla Cola" delivery truck — and every
footprint fits the paper's 8.8 m × 2.8 m patch. Capabilities are ordered as in the
paper: the jeep (short, high, all-wheel drive) traverses the widest range of
terrain; carla_cola (9 t on two driven wheels) is the weakest climber; the
mercedes_van (long wheelbase, low clearance) high-centres on sharp ridges.

A name becomes a spec once, where it enters (a profile's vehicle list, ``dgt plan
--vehicle``: :func:`~dgt_lib.core.vehicle_range.resolve_vehicle`); the spec then flows down.

Example::

    from dgt_lib.core.vehicles import get_vehicle
    jeep = get_vehicle("jeep")
    jeep.min_turn_radius_m   # 3.5 m
"""

from __future__ import annotations

from pathlib import Path

from dgt_lib.core.config import VEHICLES
from dgt_lib.core.vehicle_file import load_vehicle
from dgt_lib.core.vehicle_spec import VehicleSpec

NAMED_VEHICLE_DIR = Path(__file__).resolve().parent / "named_vehicles"
"""The named vehicles' files, ``<name>.toml`` (package data, docs/vehicles.md's format)."""

VEHICLE_SPECS: dict[str, VehicleSpec] = {
    name: load_vehicle(NAMED_VEHICLE_DIR / f"{name}.toml") for name in VEHICLES}
"""The named vehicles' specs, in head order (:data:`~dgt_lib.core.config.VEHICLES`)."""


class UnknownVehicleError(ValueError):
    """A vehicle name that is not one of :data:`dgt_lib.core.config.VEHICLES`."""


def get_vehicle(name: str | VehicleSpec) -> VehicleSpec:
    """The named vehicle ``name`` (a spec passes through unchanged)."""
    if isinstance(name, VehicleSpec):
        return name
    try:
        return VEHICLE_SPECS[name]
    except (KeyError, TypeError):
        raise UnknownVehicleError(
            f"unknown vehicle {name!r}; valid vehicles: {', '.join(VEHICLES)}"
        ) from None


def is_named(spec: VehicleSpec) -> bool:
    """Whether ``spec`` is exactly one of the named vehicles (a network has a head for it
    and the cache has its maps)."""
    return VEHICLE_SPECS.get(spec.name) == spec

