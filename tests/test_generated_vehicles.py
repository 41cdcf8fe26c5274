"""Generated training vehicles: valid specs that fit the patch, the same for a seed, and
each one a MuJoCo vehicle that drives forward and stays upright on flat ground."""

import math

import numpy as np
import pytest

from dgt_lib.core.vehicle_generator import PATCH_LENGTH_M, PATCH_WIDTH_M, generated_vehicles
from dgt_lib.core.vehicle_range import RANGE_FIELDS
from dgt_lib.core.vehicle_rules import check_vehicle, spec_fields
from dgt_lib.core.vehicles import VEHICLE_SPECS
from dgt_lib.world.simulator import Simulator
from dgt_lib.world.worlds import from_heightmap

GENERATED = generated_vehicles()


def test_twelve_named_valid_vehicles_that_fit_the_patch():
    assert [v.name for v in GENERATED] == [f"gen_{i:02d}" for i in range(12)]
    for v in GENERATED:
        assert check_vehicle(v) is v
        assert v.length_m <= PATCH_LENGTH_M and v.width_m <= PATCH_WIDTH_M


def test_the_same_seed_gives_the_same_vehicles_and_another_seed_others():
    assert generated_vehicles(12, seed=0) == GENERATED
    assert generated_vehicles(3, seed=1) != GENERATED[:3]
    assert generated_vehicles(0) == []


def test_generated_vehicles_lie_near_the_named_ones_and_spread_between_them():
    """Mild extrapolation: no field more than 30 % beyond the named vehicles' range; and
    the set is not four copies: the masses and climbs spread over the range."""
    named = [spec_fields(v) for v in VEHICLE_SPECS.values()]
    for f in RANGE_FIELDS:
        lo, hi = min(r[f] for r in named), max(r[f] for r in named)
        for v in GENERATED:
            assert lo / 1.3 <= spec_fields(v)[f] <= hi * 1.3, (v.name, f)
    masses = [v.mass_kg for v in GENERATED]
    assert len(set(masses)) == len(masses) and max(masses) > 2 * min(masses)
    assert np.ptp([v.max_climb_deg for v in GENERATED]) > 10.0


def test_derived_fields_follow_physics_not_the_mix():
    for v in GENERATED:
        decel_g = 4 * v.brake_torque_nm / (v.mass_kg * 9.81 * v.wheel_radius_m)
        assert 0.9 < decel_g < 2.0, v.name  # named vehicles: 1.1 … 1.65 g
        assert 0.0 < v.camera.up_m + v.wheel_radius_m <= v.height_m


@pytest.fixture(scope="module")
def flat():
    return from_heightmap(np.zeros((50, 100)), 0.4, origin=(0.0, 0.0))


@pytest.mark.parametrize("spec", GENERATED, ids=lambda v: v.name)
def test_each_generated_vehicle_drives_forward_and_stays_upright(flat, spec):
    sim = Simulator(flat, spec)
    start = sim.reset(8.0, 10.0, 0.0, settle_s=0.5)
    assert start.wheel_contacts.all() and not start.chassis_contact
    for _ in range(75):  # 3 s at 25 Hz, about a third of full throttle
        st = sim.step(throttle=0.35)
    assert st.done_reason is None
    # forward along +x (the named vehicles: carla_cola 2.2 m, the jeep 6.9 m)
    assert st.position[0] - start.position[0] > 1.5 and st.speed_mps > 1.0
    assert abs(st.position[1] - start.position[1]) < 0.5
    assert abs(st.roll) < math.radians(5) and abs(st.pitch) < math.radians(5)
    assert st.wheel_contacts.all() and not st.chassis_contact
