"""The physical premises the reproduction rests on, each measured on the real worlds.

Flat ground: every vehicle holds 5 m/s, drives straight, and turns like the
kinematic bicycle. Hill (Experiment 1): carla_cola cannot climb Route B's steep
section but descends it under control, climbs Route A; the jeep climbs Route B.
Ridge (Experiment 2): the mercedes_van is immobilized on the sharp ridge, the jeep
crosses it, the mercedes_van crosses the smoothed section.
"""

import math

import numpy as np
import pytest

from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.navigation.drive import drive_straight, follow_path
from dgt_lib.world.simulator import Simulator
from dgt_lib.world.terrain import get_world, make_training
from dgt_lib.world.worlds import from_heightmap


def ground(world, landmark: str) -> float:
    """The terrain's height [m] at one of the world's landmarks."""
    return float(world.height_at(*world.landmarks[landmark]))

SMOKE = get_profile("smoke")


@pytest.fixture(scope="module")
def flat():
    return from_heightmap(np.zeros((60, 220)), 0.4)  # 88 m × 24 m


@pytest.mark.parametrize("name", VEHICLES)
def test_flat_ground_holds_5_mps_and_drives_straight(flat, name):
    sim = Simulator(flat, name)
    tr = drive_straight(sim, 6.0, 12.0, 0.0, speed_mps=5.0, duration_s=15.0)
    assert tr.end_reason == "timeout"
    in_band = np.abs(tr.speed_mps - 5.0) <= 0.25
    first = tr.time_s[np.argmax(in_band)]
    assert in_band.any() and first <= 5.0
    assert np.all(in_band[tr.time_s >= 8.0])  # and stays there
    travelled = tr.position[:, 0] - tr.position[0, 0]
    over_50 = travelled <= 50.0
    assert travelled[-1] > 50.0
    assert np.abs(tr.position[over_50, 1] - 12.0).max() < 0.2


@pytest.mark.parametrize("name", VEHICLES)
def test_yaw_rate_matches_kinematic_bicycle(name):
    sim = Simulator(from_heightmap(np.zeros((150, 150)), 0.4), name)
    steer = 0.3
    tr_state = []
    sim.reset(30.0, 30.0, 0.0)
    for _ in range(150):  # 6 s
        tr_state.append(sim.step(speed_cmd_mps=5.0, steer=steer))
    late = tr_state[100:]
    measured = np.mean([s.yaw_rate for s in late])
    speed = np.mean([s.speed_mps for s in late])
    v = sim.vehicle
    kinematic = speed * math.tan(steer * v.max_steer_rad) / v.wheelbase_m  # ω = v·tan δ / L
    assert measured == pytest.approx(kinematic, rel=0.10)


@pytest.fixture(scope="module")
def hill():
    return get_world("hill", SMOKE)


def test_carla_cola_cannot_ascend_route_b(hill):
    sim = Simulator(hill, "carla_cola")
    tr = follow_path(sim, hill.routes["B"], max_time_s=60.0)
    top, bottom = (ground(hill, n) for n in ("B_steep_top", "B_steep_bottom"))
    assert tr.end_reason == "immobilized"
    assert tr.position[:, 2].max() < bottom + 0.5 * (top - bottom)  # stalls low
    assert tr.speed_mps.min() < -0.5  # and rolls back


def test_carla_cola_descends_route_b_under_control(hill):
    sim = Simulator(hill, "carla_cola")
    tr = follow_path(sim, hill.routes["B"][::-1], max_time_s=60.0)
    assert tr.end_reason == "goal"
    steep = np.abs(np.degrees(tr.pitch)) > 15.0
    assert steep.sum() * 0.04 > 2.0  # it did drive down the steep section ...
    assert np.abs(tr.speed_mps).max() < 6.0  # ... without running away


def test_carla_cola_ascends_route_a(hill):
    tr = follow_path(Simulator(hill, "carla_cola"), hill.routes["A"], max_time_s=90.0)
    assert tr.end_reason == "goal"
    assert tr.position[-1, 2] > ground(hill, "summit")


def test_jeep_ascends_route_b(hill):
    tr = follow_path(Simulator(hill, "jeep"), hill.routes["B"], max_time_s=40.0)
    assert tr.end_reason == "goal"
    assert tr.position[-1, 2] > ground(hill, "summit")


@pytest.fixture(scope="module")
def ridge():
    return get_world("ridge", SMOKE)


def _crossing(world, landmark, dx=0.0, oblique_deg=0.0):
    """A straight 28 m crossing of the ridge, ``oblique_deg`` off perpendicular."""
    x, y = world.landmarks[landmark]
    u = 14.0 * np.array([np.sin(np.radians(oblique_deg)), np.cos(np.radians(oblique_deg))])
    return np.array([[x + dx, y] - u, [x + dx, y] + u])


@pytest.mark.parametrize("dx, oblique_deg", [(0.0, 0.0), (15.0, 0.0), (0.0, 30.0)])
def test_mercedes_van_immobilized_on_sharp_ridge(ridge, dx, oblique_deg):
    path = _crossing(ridge, "sharp_crossing", dx, oblique_deg)
    tr = follow_path(Simulator(ridge, "mercedes_van"), path, max_time_s=30.0)
    y_ridge = ridge.landmarks["sharp_crossing"][1]
    assert tr.end_reason == "immobilized"
    assert tr.chassis_contact.any()  # high-centred
    assert tr.position[:, 1].max() < y_ridge + 2.0


@pytest.mark.parametrize("dx, oblique_deg", [(0.0, 0.0), (15.0, 0.0), (0.0, 30.0)])
def test_jeep_crosses_sharp_ridge(ridge, dx, oblique_deg):
    path = _crossing(ridge, "sharp_crossing", dx, oblique_deg)
    tr = follow_path(Simulator(ridge, "jeep"), path, max_time_s=30.0)
    assert tr.end_reason == "goal"


def test_mercedes_van_crosses_smooth_section(ridge):
    tr = follow_path(Simulator(ridge, "mercedes_van"), _crossing(ridge, "smooth_crossing"),
                     max_time_s=30.0)
    assert tr.end_reason == "goal" and not tr.chassis_contact.any()


def test_same_seed_same_world_same_trajectory():
    w = SMOKE.worlds
    runs = []
    for _ in range(2):  # two independently generated worlds from one seed
        world = make_training(w.eval_size_m, w.hfield_resolution_m, seed=SMOKE.seed + 7)
        x, y = world.landmarks["center"]
        runs.append(drive_straight(Simulator(world, "jeep"), x, y, 0.3, duration_s=6.0))
    assert np.array_equal(runs[0].position, runs[1].position)
    assert np.ptp(runs[0].position[:, 2]) > 0.1  # on real, uneven terrain
