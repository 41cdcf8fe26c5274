"""Procedurally generated training vehicles: specs within and a little beyond the four
named ones (docs/vehicles.md), for a network conditioned on vehicle properties
(:mod:`dgt_lib.beyond.conditioned`) to learn from more than four points of vehicle space.

Each generated vehicle mixes the four named vehicles in a normalised feature space: the
logarithms of its lengths, mass and motor torque, its steering angle, its braking
deceleration and its drag coefficient. Weights w (Σ w = 1) are drawn from a Dirichlet
distribution and pushed away from the centre by a factor 1 + e, e ~ U(0, 0.25), so
some weights are negative (a mild extrapolation); every feature then gets an independent
log-normal jitter (σ = 5 %), so the mix is not a line between two vehicles. The drive
is all-wheel with the jeep's weight as probability, at least 1/3: with the jeep the only
all-wheel drive among the named vehicles, climbing ability would otherwise always come
with the jeep's other features, and a network could not tell them apart. Derived
fields follow physics, not the mix: the brake torque from the braking deceleration, mass
and wheel radius, the drag area from the drag coefficient and the frontal area, the
camera mount from the geometry (:func:`~dgt_lib.core.vehicle_rules.default_camera`). A
draw that breaks a rule of :mod:`dgt_lib.core.vehicle_rules` or does not fit the
paper's 8.8 m × 2.8 m patch is drawn again.

Example::

    from dgt_lib.core.vehicle_generator import generated_vehicles
    specs = generated_vehicles(12, seed=0)    # gen_00 … gen_11
"""

from __future__ import annotations

import math

import numpy as np

from dgt_lib.core.vehicle_rules import (
    InvalidVehicleError,
    check_vehicle,
    default_camera,
)
from dgt_lib.core.vehicle_spec import GRAVITY_MPS2, VehicleSpec
from dgt_lib.core.vehicles import VEHICLE_SPECS

PATCH_LENGTH_M, PATCH_WIDTH_M = 8.8, 2.8
"""The paper's patch [m]: every generated footprint fits inside it."""
EXTRAPOLATION = 0.25  # largest push of the mixing weights away from the centre
JITTER = 0.05  # σ of each feature's independent log-normal jitter
DIRICHLET_ALPHA = 0.4  # < 1: mixes near one or two named vehicles are common
LOG_FIELDS: tuple[str, ...] = (
    "wheelbase_m", "track_m", "length_m", "width_m", "height_m", "ground_clearance_m",
    "wheel_radius_m", "mass_kg", "drive_torque_nm")
"""Fields mixed as logarithms (so a ratio such as track/width mixes as a ratio)."""
AWD_SHARE_MIN = 1 / 3  # chance of all-wheel drive at least this, whatever the mix
MAX_DRAWS = 1000  # per vehicle; a generator that needs more has a broken rule


def brake_deceleration_g(spec: VehicleSpec) -> float:
    """Deceleration [g] of all four brakes at full torque: 4·τ_brake / (m·g·r)."""
    return 4 * spec.brake_torque_nm / (spec.mass_kg * GRAVITY_MPS2 * spec.wheel_radius_m)


def drag_coefficient(spec: VehicleSpec) -> float:
    """C_d = drag_area / (width · height): the drag area per frontal area."""
    return spec.drag_area_m2 / (spec.width_m * spec.height_m)


def _features(spec: VehicleSpec) -> np.ndarray:
    """The mixed features of one spec (see the module docstring)."""
    logs = [math.log(getattr(spec, f)) for f in LOG_FIELDS]
    return np.array(logs + [math.degrees(spec.max_steer_rad), brake_deceleration_g(spec),
                            drag_coefficient(spec)])


def _draw(rng: np.random.Generator, name: str, table: np.ndarray) -> VehicleSpec:
    """One candidate: mixing weights, jitter, derived fields, rounded to a readable spec."""
    n = len(table)
    w = rng.dirichlet(np.full(n, DIRICHLET_ALPHA))
    w = w + rng.uniform(0, EXTRAPOLATION) * (w - 1.0 / n)  # Σ w stays 1
    f = w @ table
    f[: len(LOG_FIELDS)] += rng.normal(0, JITTER, len(LOG_FIELDS))
    f[len(LOG_FIELDS):] *= np.exp(rng.normal(0, JITTER, 3))
    g = {k: round(math.exp(v), 2) for k, v in zip(LOG_FIELDS, f, strict=False)}
    g["mass_kg"] = round(g["mass_kg"], -1)
    g["drive_torque_nm"] = round(g["drive_torque_nm"], -1)
    steer_deg, decel_g, cd = (float(x) for x in f[len(LOG_FIELDS):])
    awd_share = float(np.clip(w[list(VEHICLE_SPECS).index("jeep")], AWD_SHARE_MIN, 1))
    brake = round(decel_g * g["mass_kg"] * GRAVITY_MPS2 * g["wheel_radius_m"] / 4, -1)
    return VehicleSpec(
        name=name, **g, drive="awd" if rng.random() < awd_share else "rwd",
        brake_torque_nm=brake, max_speed_mps=20.0,
        max_steer_rad=math.radians(round(steer_deg * 2) / 2),
        camera=default_camera(g["length_m"], g["height_m"], g["ground_clearance_m"],
                              g["wheel_radius_m"]),
        drag_area_m2=round(cd * g["width_m"] * g["height_m"], 2),
        color=tuple(round(float(c), 2) for c in rng.uniform(0.15, 0.9, 3)),
    )


def generated_vehicles(n: int = 12, seed: int = 0) -> list[VehicleSpec]:
    """``n`` generated vehicles ``gen_00``, ``gen_01`` …, the same for the same seed;
    each passes :func:`~dgt_lib.core.vehicle_rules.check_vehicle` and fits the patch."""
    if n < 0:
        raise ValueError(f"n must be ≥ 0, got {n}")
    rng = np.random.default_rng(seed)
    table = np.stack([_features(s) for s in VEHICLE_SPECS.values()])  # (4, features)
    out = []
    for i in range(n):
        name = f"gen_{i:02d}"
        for _ in range(MAX_DRAWS):
            spec = _draw(rng, name, table)
            if spec.length_m > PATCH_LENGTH_M or spec.width_m > PATCH_WIDTH_M:
                continue
            try:
                out.append(check_vehicle(spec))
                break
            except InvalidVehicleError:
                continue
        else:
            raise RuntimeError(f"{name}: no valid draw in {MAX_DRAWS}")
    return out

