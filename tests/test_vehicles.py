"""The four vehicle specs: names, geometry, derived quantities, capability order."""

import math

import pytest

from dgt_lib.core.config import VEHICLES
from dgt_lib.core.vehicles import VEHICLE_SPECS, UnknownVehicleError, get_vehicle
from dgt_lib.world.simulator import ackermann_angles
from dgt_lib.world.worlds import PATCH_SIZE_M


def test_vehicles_in_head_order():
    assert tuple(VEHICLE_SPECS) == VEHICLES == ("jeep", "vw_van", "mercedes_van", "carla_cola")


def test_unknown_vehicle_lists_valid_names():
    with pytest.raises(UnknownVehicleError, match="jeep, vw_van, mercedes_van, carla_cola"):
        get_vehicle("tractor")


@pytest.mark.parametrize("name", VEHICLES)
def test_footprint_fits_patch_and_geometry_is_consistent(name):
    v = get_vehicle(name)
    assert v.length_m <= PATCH_SIZE_M[0] and v.width_m <= PATCH_SIZE_M[1]
    assert v.wheelbase_m + 2 * v.wheel_radius_m <= v.length_m + 0.3
    assert v.track_m < v.width_m
    assert 0 < v.ground_clearance_m < v.height_m
    assert v.min_turn_radius_m == pytest.approx(v.wheelbase_m / math.tan(v.max_steer_rad))


def test_capabilities_ordered_as_in_paper():
    climb = {n: get_vehicle(n).max_climb_deg for n in VEHICLES}
    assert max(climb, key=climb.get) == "jeep"
    assert min(climb, key=climb.get) == "carla_cola"
    clearance = {n: get_vehicle(n).ground_clearance_m for n in VEHICLES}
    assert max(clearance, key=clearance.get) == "jeep"
    # Long and low: the mercedes_van has the worst clearance-to-wheelbase ratio.
    ratio = {n: get_vehicle(n).ground_clearance_m / get_vehicle(n).wheelbase_m for n in VEHICLES}
    assert min(ratio, key=ratio.get) == "mercedes_van"


@pytest.mark.parametrize("steer", [0.3, -0.7, 1.0])
def test_ackermann_wheels_share_one_turn_centre(steer):
    v = get_vehicle("mercedes_van")
    left, right = ackermann_angles(steer, v)
    radius = v.wheelbase_m / math.tan(steer * v.max_steer_rad)
    assert v.wheelbase_m / math.tan(left) == pytest.approx(radius - v.track_m / 2)
    assert v.wheelbase_m / math.tan(right) == pytest.approx(radius + v.track_m / 2)
    inner, outer = (left, right) if steer > 0 else (right, left)
    assert abs(inner) > abs(outer)
    assert ackermann_angles(0.0, v) == (0.0, 0.0)


def test_body_centre_turns_wider_than_the_rear_axle():
    import math

    from dgt_lib.core.vehicles import VEHICLE_SPECS

    for spec in VEHICLE_SPECS.values():
        r_c = spec.centre_turn_radius_m
        assert r_c > spec.min_turn_radius_m
        assert math.isclose(r_c**2, spec.min_turn_radius_m**2 + (spec.wheelbase_m / 2) ** 2)
