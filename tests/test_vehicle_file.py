"""Vehicles from TOML files: every rule of the tables stops a bad spec with one line
naming its field; a valid file loads; a vehicle outside the training range warns."""

import math
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dgt_lib.core.vehicle_file import load_vehicle, parse_vehicle, vehicle_toml
from dgt_lib.core.vehicle_range import VehicleRangeWarning, resolve_vehicle, training_ranges
from dgt_lib.core.vehicle_rules import (
    CROSS_RULES,
    FIELD_RULES,
    OPTIONAL_FIELDS,
    InvalidVehicleError,
    check_fields,
    default_camera,
    spec_fields,
)
from dgt_lib.core.vehicles import VEHICLE_SPECS, get_vehicle
from dgt_lib.world.mujoco_model import build_model
from dgt_lib.world.worlds import from_heightmap

tomllib = pytest.importorskip("tomllib")  # Python ≥ 3.11
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "my_truck.toml"
NAMED = list(VEHICLE_SPECS)


def _file(fields: dict) -> dict:
    """Flat fields → the nested dict a TOML file parses into."""
    data = {k: v for k, v in fields.items() if not k.startswith("camera.")}
    data["camera"] = {k.removeprefix("camera."): v for k, v in fields.items()
                      if k.startswith("camera.")}
    return data


@pytest.mark.parametrize("name", NAMED)
def test_named_vehicles_pass_and_read_back_from_their_file_identically(name):
    spec = get_vehicle(name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # inside the training range: no warning
        back = parse_vehicle(tomllib.loads(vehicle_toml(spec)))
    assert back == spec


def _model_bytes(model: mujoco.MjModel) -> bytes:
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


@pytest.mark.parametrize("name", NAMED)
def test_a_vehicle_read_from_a_file_builds_the_named_vehicles_model_to_the_bit(name):
    flat = from_heightmap(np.zeros((30, 30)), 0.4)
    spec = get_vehicle(name)
    from_file = parse_vehicle(tomllib.loads(vehicle_toml(spec)))
    assert _model_bytes(build_model(flat, from_file)) == _model_bytes(build_model(flat, name))


@pytest.mark.parametrize("field", list(FIELD_RULES))
@pytest.mark.parametrize("name", NAMED)
def test_each_impossible_field_value_is_one_line_naming_the_field(field, name):
    fields = spec_fields(get_vehicle(name))
    fields[field] = FIELD_RULES[field].outside
    with pytest.raises(InvalidVehicleError) as err:
        parse_vehicle(_file(fields), "car.toml")
    message = str(err.value)
    assert "\n" not in message and message.startswith("car.toml: ")
    assert f"{field} = " in message and FIELD_RULES[field].allowed in message


@pytest.mark.parametrize("rule", CROSS_RULES, ids=lambda r: "+".join(r.names))
@pytest.mark.parametrize("name", NAMED)
def test_each_rule_between_fields_stops_its_breaking_values(rule, name):
    fields = spec_fields(get_vehicle(name))
    check_fields(fields)  # the named vehicle passes …
    fields.update(rule.breaking)
    with pytest.raises(InvalidVehicleError, match="do not fit together") as err:
        check_fields(fields)  # … and breaking this rule breaks it, first
    assert rule.allowed in str(err.value)
    assert all(f"{n} = " in str(err.value) for n in rule.names)


def test_an_unknown_field_lists_the_valid_ones():
    data = _file(spec_fields(get_vehicle("jeep")))
    data["horsepower"] = 200
    with pytest.raises(InvalidVehicleError, match="unknown field 'horsepower'; valid fields: "
                       "name, wheelbase_m"):
        parse_vehicle(data)
    data = _file(spec_fields(get_vehicle("jeep")))
    data["camera"]["roll_deg"] = 1.0
    with pytest.raises(InvalidVehicleError, match="unknown field 'camera.roll_deg'"):
        parse_vehicle(data)


@pytest.mark.parametrize("field", [f for f in FIELD_RULES if not f.startswith("camera.")
                                   and f not in OPTIONAL_FIELDS])
def test_a_missing_required_field_is_named(field):
    data = _file(spec_fields(get_vehicle("carla_cola")))
    del data[field]
    with pytest.raises(InvalidVehicleError, match=f"missing required field '{field}'"):
        parse_vehicle(data)


@pytest.mark.parametrize(("field", "value", "want"), [
    ("mass_kg", "heavy", "a number"), ("wheelbase_m", True, "a number"),
    ("drive", 4, "a string"), ("color", "red", "a list of numbers"),
    ("camera", 3.0, "a table")])
def test_a_value_of_the_wrong_type_says_what_was_expected(field, value, want):
    data = _file(spec_fields(get_vehicle("jeep")))
    data[field] = value
    with pytest.raises(InvalidVehicleError, match=f"{field} = .* has the wrong type: "
                       f"{field} must be {want}"):
        parse_vehicle(data)


def test_the_example_truck_loads_between_the_van_and_the_truck_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        truck = load_vehicle(EXAMPLE)
    van, cola = get_vehicle("vw_van"), get_vehicle("carla_cola")
    assert truck.name == "my_truck"
    for f in ("mass_kg", "wheelbase_m", "length_m", "drive_torque_nm"):
        assert getattr(van, f) < getattr(truck, f) < getattr(cola, f), f
    assert cola.max_climb_deg < truck.max_climb_deg < van.max_climb_deg
    # no [camera] table in the example: the camera is mounted from the geometry
    assert truck.camera == default_camera(truck.length_m, truck.height_m,
                                          truck.ground_clearance_m, truck.wheel_radius_m)
    assert math.isclose(math.degrees(truck.max_steer_rad), 34.0)


def test_a_vehicle_outside_the_training_range_warns_naming_each_field_and_range(tmp_path):
    fields = spec_fields(get_vehicle("carla_cola"))
    fields.update(mass_kg=20000.0, max_steer_deg=45.0)
    path = tmp_path / "big.toml"
    path.write_text(vehicle_toml(parse_vehicle(_file(fields))))
    with pytest.warns(VehicleRangeWarning) as caught:
        spec = resolve_vehicle(path)
    assert spec.mass_kg == 20000.0  # a warning, not an error: the vehicle still loads
    (message,) = [str(w.message) for w in caught]
    lo, hi = training_ranges()["mass_kg"]
    assert message.startswith(f"{path}: ")
    assert f"mass_kg = 20000 (trained on {lo:g} … {hi:g})" in message
    assert "max_steer_deg = 45" in message and "wheelbase_m" not in message


def test_a_file_that_is_not_toml_or_not_there_names_itself(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(InvalidVehicleError, match="bad.toml: not valid TOML"):
        load_vehicle(bad)
    with pytest.raises(InvalidVehicleError, match="missing.toml: cannot read it"):
        load_vehicle(tmp_path / "missing.toml")


def test_a_300_digit_integer_or_a_non_utf8_file_is_one_line_naming_the_file(tmp_path):
    text = EXAMPLE.read_text(encoding="utf-8")
    key = next(line.split("=")[0].strip() for line in text.splitlines()
               if line.strip().startswith("wheelbase_m"))
    huge = tmp_path / "huge.toml"
    huge.write_text("\n".join(f"{key} = {'9' * 400}" if line.strip().startswith(key)
                              else line for line in text.splitlines()), encoding="utf-8")
    with pytest.raises(InvalidVehicleError) as err:
        load_vehicle(huge)
    assert str(err.value).startswith(f"{huge}: wheelbase_m = 999")
    assert "too large" in str(err.value) and "9" * 61 not in str(err.value)
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'name = "b\xff"\n')
    with pytest.raises(InvalidVehicleError, match=f"^{latin}: not UTF-8 text"):
        load_vehicle(latin)


def test_a_field_of_the_wrong_type_names_the_file(tmp_path):
    path = tmp_path / "typed.toml"
    path.write_text(EXAMPLE.read_text(encoding="utf-8").replace(
        "wheelbase_m = ", 'wheelbase_m = "long" #', 1), encoding="utf-8")
    with pytest.raises(InvalidVehicleError, match=f"^{path}: wheelbase_m = 'long' has the "
                                                  "wrong type"):
        load_vehicle(path)
