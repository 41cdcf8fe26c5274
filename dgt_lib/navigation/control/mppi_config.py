"""The footprint a vehicle gives the MPPI tracker, and MPPI settings typed on a command line.
The settings themselves are the Profile's ``mppi`` section (:mod:`dgt_lib.core.controller`)."""

from __future__ import annotations

from dataclasses import fields

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.core.vehicle_spec import footprint_circles


def vehicle_footprint(vehicle, margin_m: float = 0.2) -> dict[str, object]:
    """Footprint circles for the occupancy critic from a ``VehicleSpec``-like object
    (``wheelbase_m``, ``length_m``, ``width_m``), as :class:`MPPIConfig` fields::

        cfg = dataclasses.replace(MPPIConfig(), **vehicle_footprint(spec))

    The planner's circles (:func:`dgt_lib.core.vehicle_spec.footprint_circles`, covering the
    length × width rectangle around the body centre) moved to the rear-axle
    reference (the body centre is ℓ/2 ahead of it, equal overhangs), radius plus
    ``margin_m``; the inflation radius is set 1.5 m beyond it.
    """
    offsets, radius = footprint_circles(vehicle.length_m, vehicle.width_m)
    radius += margin_m
    offsets = offsets + 0.5 * vehicle.wheelbase_m
    return {
        "footprint_offsets_m": tuple(round(float(o), 3) for o in offsets),
        "collision_radius_m": radius,
        "inflation_radius_m": radius + 1.5,
    }


def parse_mppi_settings(text: str) -> dict[str, object]:
    """``"lateral_accel_max=2.0,w_rate_std=0.75"`` → :class:`MPPIConfig` fields for
    ``replace(profile.mppi, **fields)``, each typed by its default (``20`` for a float field is
    20.0). Raises ValueError naming the valid fields for anything else."""
    defaults = MPPIConfig()
    out: dict[str, object] = {}
    for part in text.split(","):
        name, _, value = (p.strip() for p in part.partition("="))
        if not name or not value or not hasattr(defaults, name):
            raise ValueError(f"{part.strip()!r} is not FIELD=VALUE of an MPPI setting; fields: "
                             f"{', '.join(f.name for f in fields(MPPIConfig))}")
        out[name] = type(getattr(defaults, name))(value)
    return out
