"""What a vehicle spec may be: one table of field rules and one of rules between fields,
checked before a vehicle from a file (:mod:`dgt_lib.core.vehicle_file`) or a generated one
(:mod:`dgt_lib.core.vehicle_generator`) reaches the simulator (docs/vehicles.md).

A spec is checked as its *fields*: the :class:`~dgt_lib.core.vehicle_spec.VehicleSpec` field
names, angles in degrees (``max_steer_deg``, ``camera.pitch_down_deg``), the camera mount
as ``camera.forward_m``, ``camera.up_m``. :data:`FIELD_RULES` says what each may be,
:data:`CROSS_RULES` how they must fit together: the geometry rules follow from how
:mod:`dgt_lib.world.mujoco_model` builds the body (axles inside the body, a 0.25 m belly
under a body of positive height, the belly hanging below the wheel tops). A broken rule
is an :class:`InvalidVehicleError`, one line naming the field, its value and what is
allowed, in the words of :mod:`dgt_lib.core.constraints`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping
from dataclasses import MISSING

from dgt_lib.core.constraints import CrossRule, Rule, above, at_least, between, one_of
from dgt_lib.core.vehicle_spec import CameraMount, VehicleSpec

BELLY_HEIGHT_M = 0.25
"""Thickness of the belly box under the body [m] (``mujoco_model._add_vehicle``)."""
MAX_STEER_LIMIT_DEG = 60.0
"""The virtual centre wheel's angle must be in (0°, 60°)."""
STEER_HINGE_RAD = 1.0
"""Range ± of each front wheel's steering hinge [rad] (``mujoco_model._add_wheel``)."""
DRIVES: tuple[str, ...] = ("awd", "rwd")

CAMERA_BEHIND_FRONT_M = 0.6  # default camera: this far behind the body's front [m]
CAMERA_HEIGHT_FRACTION = 0.9  # … at this fraction of the body's height above its belly
CAMERA_PITCH_DOWN_DEG = 20.0  # … pitched down this much [deg] (every named vehicle's)


class InvalidVehicleError(ValueError):
    """A vehicle spec with an unknown, missing, mistyped or impossible field."""


def _name_rule() -> Rule:
    ok = re.compile(r"[A-Za-z0-9_-]+\Z")
    return Rule(lambda v: isinstance(v, str) and bool(ok.match(v)),
                "letters, digits, _ or - (it names cache folders)", "my truck")


def _open(low: float, high: float) -> Rule:
    return Rule(lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)
                and low < v < high, f"in ({low:g}, {high:g})", high)


def _colour() -> Rule:
    return Rule(lambda v: len(v) == 3 and all(0 <= x <= 1 for x in v),
                "three values in [0, 1] (red, green, blue)", (0.5, 0.5, 1.5))


POSITIVE, NON_NEGATIVE = above(0), at_least(0)
FINITE = Rule(lambda v: math.isfinite(v), "a finite number", math.inf)

FIELD_RULES: dict[str, Rule] = {
    "name": _name_rule(),
    "wheelbase_m": POSITIVE, "track_m": POSITIVE, "length_m": POSITIVE, "width_m": POSITIVE,
    "height_m": POSITIVE, "ground_clearance_m": NON_NEGATIVE, "wheel_radius_m": POSITIVE,
    "mass_kg": POSITIVE, "drive": one_of(*DRIVES), "drive_torque_nm": POSITIVE,
    "brake_torque_nm": POSITIVE, "max_speed_mps": POSITIVE,
    "max_steer_deg": _open(0.0, MAX_STEER_LIMIT_DEG),
    "rolling_resistance": between(0, 1, high_open=True), "drag_area_m2": NON_NEGATIVE,
    "color": _colour(),
    "camera.forward_m": FINITE, "camera.up_m": FINITE,
    "camera.pitch_down_deg": between(0, 90, high_open=True),
}
"""Every field's allowed values; the file's field names (angles in degrees)."""

FIELD_TYPES: dict[str, type] = {name: float for name in FIELD_RULES}
FIELD_TYPES.update({"name": str, "drive": str, "color": tuple})
"""What each field's value is: a number (an integer is taken as a float), a string, or
``color``'s three numbers."""

OPTIONAL_FIELDS: dict[str, object] = {
    f.name: f.default for f in dataclasses.fields(VehicleSpec) if f.default is not MISSING}
"""Fields a file may leave out, with their defaults (``VehicleSpec``'s); the camera table
may be left out too (:func:`default_camera`)."""
CAMERA_FIELDS: tuple[str, ...] = ("forward_m", "up_m", "pitch_down_deg")


def inner_wheel_angle_rad(f: Mapping[str, object]) -> float:
    """The inner front wheel's angle [rad] at full steer: atan(L / (R − T/2)), R = L / tan δ
    (``simulator.ackermann_angles``); above π/2 when the turn's centre lies inside the track."""
    wheelbase, track = float(f["wheelbase_m"]), float(f["track_m"])
    radius = wheelbase / math.tan(math.radians(float(f["max_steer_deg"])))
    return math.atan2(wheelbase, radius - track / 2)


CROSS_RULES: tuple[CrossRule, ...] = (
    CrossRule(("wheelbase_m", "length_m"), lambda f: f["wheelbase_m"] < f["length_m"],
              "the axles lie inside the body (wheelbase_m < length_m)",
              {"wheelbase_m": 7.0, "length_m": 6.5}),
    CrossRule(("track_m", "width_m"), lambda f: f["track_m"] <= f["width_m"],
              "the wheels lie under the body (track_m ≤ width_m)",
              {"track_m": 2.6, "width_m": 2.5}),
    CrossRule(("wheel_radius_m", "wheelbase_m"),
              lambda f: 2 * f["wheel_radius_m"] < f["wheelbase_m"],
              "front and rear wheels do not overlap (2·wheel_radius_m < wheelbase_m)",
              {"wheel_radius_m": 1.3, "wheelbase_m": 2.5, "length_m": 7.0}),
    CrossRule(("wheel_radius_m", "track_m"), lambda f: 2 * f["wheel_radius_m"] < f["track_m"],
              "left and right wheels do not overlap (2·wheel_radius_m < track_m)",
              {"wheel_radius_m": 1.0, "track_m": 1.9, "width_m": 2.0}),
    CrossRule(("ground_clearance_m", "wheel_radius_m"),
              lambda f: f["ground_clearance_m"] < 2 * f["wheel_radius_m"],
              "the belly hangs below the wheel tops (ground_clearance_m < 2·wheel_radius_m)",
              {"ground_clearance_m": 0.9, "wheel_radius_m": 0.4}),
    CrossRule(("height_m", "ground_clearance_m"),
              lambda f: f["height_m"] > f["ground_clearance_m"] + BELLY_HEIGHT_M,
              f"the body above the {BELLY_HEIGHT_M:g} m belly has a height "
              f"(height_m > ground_clearance_m + {BELLY_HEIGHT_M:g})",
              {"height_m": 0.5, "ground_clearance_m": 0.3}),
    CrossRule(("max_steer_deg", "wheelbase_m", "track_m"),
              lambda f: inner_wheel_angle_rad(f) < STEER_HINGE_RAD,
              f"at full steer the inner front wheel's Ackermann angle stays inside its "
              f"hinge's ±{STEER_HINGE_RAD:g} rad", {"max_steer_deg": 55.0}),
    CrossRule(("camera.forward_m", "length_m"),
              lambda f: abs(f["camera.forward_m"]) <= f["length_m"] / 2,
              "the camera sits along the body (|camera.forward_m| ≤ length_m / 2)",
              {"camera.forward_m": 4.0}),
    CrossRule(("camera.up_m", "ground_clearance_m", "height_m", "wheel_radius_m"),
              lambda f: f["ground_clearance_m"] < f["camera.up_m"] + f["wheel_radius_m"]
              <= f["height_m"],
              "the camera sits between the belly and the roof (ground_clearance_m < "
              "camera.up_m + wheel_radius_m ≤ height_m)", {"camera.up_m": 5.0}),
)
"""The rules between fields; ``breaking`` breaks the rule (and only it) from each of the
four named vehicles (the tests)."""


def default_camera(length_m: float, height_m: float, ground_clearance_m: float,
                   wheel_radius_m: float) -> CameraMount:
    """The camera mount a spec gets when its file has no ``[camera]`` table:
    :data:`CAMERA_BEHIND_FRONT_M` behind the body's front (not behind the rear axle), at
    :data:`CAMERA_HEIGHT_FRACTION` of the body's height above the belly, pitched
    :data:`CAMERA_PITCH_DOWN_DEG` down. Within 0.21 m of the vans' and the truck's own
    mounts; the jeep's sits 0.95 m further back, behind its bonnet."""
    up_above_ground = ground_clearance_m + CAMERA_HEIGHT_FRACTION * (
        height_m - ground_clearance_m)
    return CameraMount(forward_m=max(length_m / 2 - CAMERA_BEHIND_FRONT_M, 0.0),
                       up_m=up_above_ground - wheel_radius_m,
                       pitch_down_rad=math.radians(CAMERA_PITCH_DOWN_DEG))


def spec_fields(spec: VehicleSpec) -> dict[str, object]:
    """A spec as the flat fields the rules read (angles in degrees, ``camera.*``)."""
    derived = {"max_steer_deg": math.degrees(spec.max_steer_rad),
               "camera.forward_m": spec.camera.forward_m, "camera.up_m": spec.camera.up_m,
               "camera.pitch_down_deg": math.degrees(spec.camera.pitch_down_rad)}
    return {name: derived[name] if name in derived else getattr(spec, name)
            for name in FIELD_RULES}


def fields_to_spec(f: Mapping[str, object]) -> VehicleSpec:
    """Checked flat fields (:func:`check_fields`) → a :class:`VehicleSpec`."""
    camera = CameraMount(float(f["camera.forward_m"]), float(f["camera.up_m"]),
                         math.radians(float(f["camera.pitch_down_deg"])))
    plain = {k: v for k, v in f.items() if "." not in k and k != "max_steer_deg"}
    return VehicleSpec(**plain, max_steer_rad=math.radians(float(f["max_steer_deg"])),
                       camera=camera)


def _typed(name: str, value: object, where: str = "vehicle") -> object:
    """``value`` as ``FIELD_TYPES[name]`` wants it, or :class:`InvalidVehicleError` starting
    with ``where`` (an integer too large for a float, 300 digits, is one too)."""
    kind = FIELD_TYPES[name]
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    shown = _shown(value)
    try:
        if kind is float and number:
            return float(value)
        if kind is tuple and isinstance(value, (list, tuple)) and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
            return tuple(float(x) for x in value)
    except OverflowError:
        raise InvalidVehicleError(f"{where}: {name} = {shown} is too large for a number "
                                  "of the kit (at most about 1.8e308)") from None
    if kind is str and isinstance(value, str):
        return value
    want = {float: "a number", str: "a string", tuple: "a list of numbers"}[kind]
    raise InvalidVehicleError(f"{where}: {name} = {shown} has the wrong type: {name} must be "
                              f"{want}, not {type(value).__name__}")


def _shown(value: object, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a 300-digit integer stays one line)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit - 1]}…"


def check_fields(f: Mapping[str, object], where: str = "vehicle") -> dict[str, object]:
    """The flat fields ``f`` typed and checked against :data:`FIELD_RULES` and
    :data:`CROSS_RULES`: a copy with numbers as floats, or :class:`InvalidVehicleError`
    for the first field (in table order) that is missing, mistyped or impossible;
    ``where`` (e.g. the file) starts the message."""
    unknown = sorted(set(f) - set(FIELD_RULES))
    if unknown:
        raise InvalidVehicleError(f"{where}: unknown field {unknown[0]!r}; valid fields: "
                                  f"{', '.join(FIELD_RULES)}")
    out: dict[str, object] = {}
    for name, rule in FIELD_RULES.items():
        if name not in f:
            raise InvalidVehicleError(f"{where}: missing required field {name!r}")
        value = _typed(name, f[name], where)
        if not rule.check(value):
            raise InvalidVehicleError(f"{where}: {name} = {_shown(value)} is impossible: "
                                      f"{name} must be {rule.allowed}")
        out[name] = value
    for rule in CROSS_RULES:
        if not rule.check(out):
            given = ", ".join(f"{n} = {out[n]:g}" for n in rule.names)
            raise InvalidVehicleError(f"{where}: {given} do not fit together: {rule.allowed}")
    return out


def check_vehicle(spec: VehicleSpec) -> VehicleSpec:
    """``spec`` itself when it passes every rule, else :class:`InvalidVehicleError`."""
    check_fields(spec_fields(spec), where=spec.name)
    return spec
