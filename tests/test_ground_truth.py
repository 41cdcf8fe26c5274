"""Ground-truth directional locomotion: driving a vehicle through a cell at heading θ
measures the L the network is trained to predict (dgt_lib.evaluation.ground_truth)."""

import math

import numpy as np
import pytest

from dgt_lib.core.config import VEHICLES, GroundTruthConfig
from dgt_lib.core.geometry import heading_bins
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.ground_truth import (
    L_STANDING,
    STATUSES,
    GroundTruth,
    candidate_cells,
    cell_strata,
    drive_through,
    sample_cells,
)
from dgt_lib.world.terrain import get_world
from dgt_lib.world.worlds import from_heightmap

RES = 0.4
SLOPE_DEG = 26.0  # Route B's steep section: carla_cola descends it, cannot climb it


def _status(result):
    return STATUSES[result["status"]]


@pytest.fixture(scope="module")
def flat():
    return from_heightmap(np.zeros((120, 120), np.float32), RES, name="flat")


@pytest.fixture(scope="module")
def ramp():
    """Flat for y < 20 m, then a 26° slope rising north to a plateau 20 m up (y ≈ 61 m),
    its toe and crest rounded over ~2 m."""
    y = (np.arange(240) + 0.5) * RES
    h = np.clip((y - 20.0) * math.tan(math.radians(SLOPE_DEG)), 0.0, 20.0)
    k = np.exp(-0.5 * (np.arange(-12, 13) * RES / 1.0) ** 2)
    h = np.convolve(np.pad(h, 12, mode="edge"), k / k.sum(), mode="valid")
    return from_heightmap(np.repeat(h[:, None], 60, 1).astype(np.float32), RES, name="ramp")


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_on_flat_ground_every_vehicle_keeps_its_speed_and_l_is_one(flat, vehicle):
    for theta in (0.0, 3 * math.pi / 4):  # along the grid and diagonally
        r = drive_through(flat, vehicle, (24.0, 24.0), theta)
        assert _status(r) == "passed"
        assert r["locomotion"] > 0.98, (vehicle, theta, r)
        assert abs(r["speed_mps"] - 5.0) < 0.3 and r["cross_track_m"] < 0.3


def test_on_a_slope_the_truck_cannot_climb_uphill_l_is_far_below_downhill(ramp):
    """carla_cola stalls climbing 26° and descends it at speed: uphill L* ≪ downhill L*,
    wherever on the slope the cell lies (a cell high up: the run-up stalls below it, and
    started at rest on the cell the truck does not get 1 m on)."""
    for y in (30.0, 45.0):
        up = drive_through(ramp, "carla_cola", (12.0, y), math.pi / 2)
        down = drive_through(ramp, "carla_cola", (12.0, y), 3 * math.pi / 2)
        assert _status(up) == "stuck" and up["locomotion"] == L_STANDING, up
        assert _status(down) == "passed" and down["locomotion"] > 0.8, down
    jeep = drive_through(ramp, "jeep", (12.0, 30.0), math.pi / 2)  # the jeep climbs 26°
    assert _status(jeep) == "passed" and jeep["locomotion"] > 0.8


def test_route_b_of_the_hill_is_costly_uphill_and_cheap_downhill_for_carla_cola():
    """Experiment 1's premise measured: the middle of Route B's steep section. Uphill the
    truck rolls back down and charges the slope again until its time is up — it never
    crosses the cell, whatever its last second shows."""
    hill = get_world("hill", "smoke")
    bottom, top = (np.asarray(hill.landmarks[n]) for n in ("B_steep_bottom", "B_steep_top"))
    cell = 0.5 * (bottom + top)
    up = drive_through(hill, "carla_cola", cell, math.pi / 2)
    down = drive_through(hill, "carla_cola", cell, 3 * math.pi / 2)
    assert _status(up) == "stuck" and up["locomotion"] == L_STANDING, up
    assert _status(down) == "passed" and down["locomotion"] > 0.9, down


def test_an_obstacle_in_the_run_up_is_not_measured_one_at_the_cell_is(flat):
    """A trunk 10 m before the cell blocks the run-up (not measured); a trunk just past
    the cell stops the vehicle with the cell under it (L* of a vehicle standing still)."""
    trees = np.array([[14.0, 24.0, 0.3, 6.0], [25.0, 40.0, 0.3, 6.0]], np.float32)
    world = from_heightmap(np.zeros((120, 120), np.float32), RES, trees=trees, name="trees")
    blocked = drive_through(world, "jeep", (24.0, 24.0), 0.0)
    assert _status(blocked) == "blocked_tree" and math.isnan(blocked["locomotion"])
    assert _status(drive_through(world, "jeep", (24.0, 24.0), math.pi)) == "passed"
    stuck = drive_through(world, "jeep", (24.0, 39.0), math.pi / 2)
    assert _status(stuck) == "stuck" and stuck["locomotion"] == L_STANDING
    assert -get_vehicle("jeep").length_m / 2 <= stuck["stop_along_m"] < 0


def test_a_cliff_in_the_run_up_blocks_it_and_the_sample_is_not_measured():
    """A 3 m cliff 10 m before a cell on the plateau: the run-up stops far short of it and
    the vehicle drives off from rest on the cell, so L* at speed is unknown; from the
    plateau side the same cell is measured."""
    h = np.where((np.arange(120) + 0.5) * RES > 14.0, 3.0, 0.0).astype(np.float32)
    world = from_heightmap(np.repeat(h[None, :], 120, 0), RES, name="cliff")
    r = drive_through(world, "vw_van", (24.0, 24.0), 0.0)
    assert _status(r) == "blocked_terrain" and math.isnan(r["locomotion"])
    assert r["stop_along_m"] < -10.0
    assert _status(drive_through(world, "vw_van", (24.0, 24.0), math.pi)) == "passed"


def test_a_ridge_stops_the_van_on_it_and_charges_no_cell_it_lies_behind():
    """Experiment 2's sharp crest, the mercedes_van northbound: a cell on the crest, or
    under the stuck van, is stuck; a cell 5 m beyond it was never under the van (the
    van standing there drives off) and is not measured; a cell 1.5 m before it is crossed
    at speed, L* lowered only by the stall in the window's second half. The jeep crosses."""
    ridge = get_world("ridge", "smoke")
    x, y = ridge.landmarks["sharp_crossing"]
    on, beyond, before = ((drive_through(ridge, "mercedes_van", (x, y + dy), math.pi / 2))
                          for dy in (0.0, 5.0, -1.5))
    assert _status(on) == "stuck" and on["locomotion"] == L_STANDING
    assert _status(beyond) == "blocked_terrain" and math.isnan(beyond["locomotion"])
    assert _status(before) == "passed" and 0.2 < before["locomotion"] < 0.95
    jeep = drive_through(ridge, "jeep", (x, y), math.pi / 2)
    assert _status(jeep) == "passed" and jeep["locomotion"] > 0.9
    # A trunk 10 m before a cell 4 m short of the crest blocks the run-up; started on the
    # cell the van drives off (the crest ahead holds it only later): not measured.
    tree = np.array([[x, y - 14.0, 0.3, 6.0]], np.float32)
    treed = from_heightmap(np.array(ridge.heights), RES, trees=tree, name="ridge_tree")
    short = drive_through(treed, "mercedes_van", (x, y - 4.0), math.pi / 2)
    assert _status(short) == "blocked_tree" and math.isnan(short["locomotion"])


def test_standing_still_reads_exp_minus_one_over_two_sigma_squared():
    assert L_STANDING == pytest.approx(math.exp(-4.5))


def test_cells_are_stratified_deterministic_and_drivable():
    hill = get_world("hill", "smoke")
    cfg = GroundTruthConfig(cells=32)
    xy, stratum = sample_cells(hill, cfg)
    again, _ = sample_cells(hill, cfg)
    np.testing.assert_array_equal(xy, again)
    assert len(xy) == 32 and len({tuple(p) for p in xy}) == 32
    ok = candidate_cells(hill, cfg)
    rows, cols = hill.grid.xy_to_cell(xy[:, 0], xy[:, 1])
    assert ok[rows, cols].all()
    x0, x1, y0, y1 = hill.grid.extent
    assert (xy.min(0) >= [x0 + 20, y0 + 20]).all() and (xy.max(0) <= [x1 - 20, y1 - 20]).all()
    assert hill.tree_distance(xy[:, 0], xy[:, 1]).min() >= cfg.tree_clearance_m
    present = np.unique(cell_strata(hill, cfg)[ok])
    assert set(stratum) == set(present)  # every stratum drawn, not only the flat majority
    steep_on_route = 4 * 3 + 2  # 18–30°, on a route: Route B's steep section
    assert np.sum((stratum // 2) == steep_on_route // 2) >= 2
    assert len(set(map(tuple, sample_cells(hill, GroundTruthConfig(cells=32, seed=1))[0]))
               - set(map(tuple, xy))) > 0


def test_ground_truth_assembles_every_drive_and_round_trips_through_arrays():
    cells = np.array([[1.0, 2.0], [3.0, 4.0]])
    passed = {"status": 0, "locomotion": 0.9, "speed_mps": 5.0, "cross_track_m": 0.1}
    blocked = {"status": STATUSES.index("blocked_terrain"), "locomotion": math.nan,
               "speed_mps": math.nan, "cross_track_m": math.nan}
    drives = {(i, k): passed for i in range(2) for k in range(4)} | {(1, 3): blocked}
    gt = GroundTruth.from_drives("w", "jeep", cells, np.array([0, 1]), 4, drives)
    assert gt.measured.sum() == 7 and np.isnan(gt.cost[1, 3])
    assert gt.cost[0, 0] == pytest.approx(0.1)
    back = GroundTruth.from_arrays(gt.to_arrays())
    np.testing.assert_array_equal(back.status, gt.status)
    np.testing.assert_allclose(back.headings, heading_bins(4))
    assert back.status_counts()["blocked_terrain"] == 1
    del drives[(0, 2)]
    with pytest.raises(ValueError, match="1 of 8 drives missing"):
        GroundTruth.from_drives("w", "jeep", cells, np.array([0, 1]), 4, drives)


def test_a_robot_from_its_own_vehicle_file_is_measured_like_a_named_vehicle(ramp):
    """my_truck (examples/my_truck.toml, a spec no network has a head for) climbs at most
    14.8°: on the 26° ramp it stalls uphill and descends at speed."""
    from pathlib import Path

    from dgt_lib.core.vehicle_file import load_vehicle

    truck = load_vehicle(Path(__file__).resolve().parents[1] / "examples" / "my_truck.toml")
    up = drive_through(ramp, truck, (12.0, 30.0), math.pi / 2)
    down = drive_through(ramp, truck, (12.0, 30.0), 3 * math.pi / 2)
    assert _status(up) == "stuck" and up["locomotion"] == L_STANDING, up
    assert _status(down) == "passed" and down["locomotion"] > 0.8, down
