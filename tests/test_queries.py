"""Experiment 3's random queries: the hazard rule (from the true heights) and the
kinematic feasibility check (Hybrid A* with the turning radius and footprint)."""

from types import SimpleNamespace

import numpy as np
import pytest

from dgt_lib.core.config import ExperimentsConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.hazards import HazardMap, belly_relief, hazard_map, vehicle_hazards
from dgt_lib.evaluation.queries import draw_random_queries, is_feasible
from dgt_lib.mapping.baselines import binary_costmap
from dgt_lib.navigation.planner import HybridAStar
from dgt_lib.world.worlds import from_heightmap

RES = 0.4
YARD_Y = 20.0  # an open yard south of y = 20 m
LEG_X = (18.5, 21.5)  # a 3 m lane north from the yard to y = 30 m …
LEG_Y_END = 30.0
BEND_Y = (27.0, 30.0)  # … that bends 90° east into a 3 m dead end to x = 32 m
BEND_X_END = 32.0


def yard_with_bent_lane() -> SimpleNamespace:
    """A 40 m × 40 m occupancy map: an open yard, and off it a 3 m wide lane that runs
    north and then bends 90° east. The jeep drives up the lane, but it cannot turn into
    the bend (its turning radius is 3.7 m), nor back out: goals in the bend are reachable
    in 2D only."""
    grid = GridSpec((0.0, 0.0), RES, (100, 100))
    x, y = grid.cell_centers()
    yard = (y > 1.0) & (y < YARD_Y) & (x > 1.0) & (x < 39.0)
    lane = (x > LEG_X[0]) & (x < LEG_X[1]) & (y >= YARD_Y - 0.5) & (y < LEG_Y_END)
    bend = (x > LEG_X[0]) & (x < BEND_X_END) & (y > BEND_Y[0]) & (y < BEND_Y[1])
    free = yard | lane | bend
    return SimpleNamespace(world="yard", grid=grid,
                           occupancy=np.where(free, 0, 1).astype(np.uint8))


def jeep_planner(maps) -> HybridAStar:
    return HybridAStar.for_vehicle(binary_costmap(maps.grid.shape), maps.occupancy, maps.grid,
                                   get_vehicle("jeep"))


def in_bend(xy) -> bool:
    return xy[0] > LEG_X[1] + 1.0 and xy[1] > BEND_Y[0] - 0.5


def test_a_goal_the_vehicle_cannot_turn_into_is_infeasible_though_reachable_in_2d():
    maps = yard_with_bent_lane()
    planner = jeep_planner(maps)
    start, bend_goal = (20.0, 5.0, np.pi / 2), (29.0, 28.5)
    r, c = maps.grid.xy_to_cell(*start[:2])
    assert np.isfinite(planner.cost_to_go(bend_goal)[r, c])  # a 2D check would accept it
    assert not is_feasible(planner, start, bend_goal)
    assert is_feasible(planner, start, (20.0, 25.0))  # straight up the lane: feasible
    assert is_feasible(planner, (5.0, 10.0, 0.0), (20.0, 25.0))  # round the yard, then up


def test_the_query_generator_keeps_only_feasible_queries():
    maps = yard_with_bent_lane()
    cfg = ExperimentsConfig(eval_distance_m=(10.0, 30.0))
    draw = draw_random_queries(maps, 8, cfg, seed=0, vehicle="jeep", margin_m=1.0)
    planner = jeep_planner(maps)
    assert len(draw.queries) == 8
    assert draw.rejected["infeasible"] > 0  # candidates with the goal in the bend
    for q in draw.queries:
        assert not in_bend(q.goal)
        assert planner.plan(q.start, q.goal).success
    assert draw.queries == draw_random_queries(maps, 8, cfg, 0, "jeep", margin_m=1.0).queries


def test_too_few_feasible_queries_is_a_clear_error():
    maps = yard_with_bent_lane()
    cfg = ExperimentsConfig(eval_distance_m=(60.0, 70.0))  # farther than the map allows
    with pytest.raises(RuntimeError, match="found only 0 of 2 random queries.*rejected"):
        draw_random_queries(maps, 2, cfg, seed=0, vehicle="jeep", margin_m=1.0)


def test_belly_relief_is_the_height_above_the_chord_between_the_axles():
    h = np.zeros((21, 21))
    h[10, :] = 0.5  # an east–west wall one cell wide, 0.5 m high
    rel = belly_relief(h, RES, half_span_m=1.2)
    assert rel[10, 10] == pytest.approx(0.5)  # across it (north–south): 0.5 above the chord
    assert rel[0, 10] == pytest.approx(0.0, abs=1e-12)
    plane = np.fromfunction(lambda r, c: 0.3 * r, (21, 21))  # a plane has no crest
    assert np.abs(belly_relief(plane, RES, 1.2)[3:-3, 3:-3]).max() < 1e-9


def test_hazards_depend_on_the_vehicle_and_come_from_the_true_heights():
    size = 101
    x = np.arange(size) * RES
    # west half flat; east half a 25° slope: steeper than the vw_van climbs, not the jeep
    ramp = np.where(x > 20.0, (x - 20.0) * np.tan(np.radians(25.0)), 0.0)
    world = from_heightmap(np.tile(ramp, (size, 1)).astype(np.float32), RES)
    assert get_vehicle("vw_van").max_climb_deg < 25.0 < get_vehicle("jeep").max_climb_deg
    van, jeep = vehicle_hazards(world, "vw_van"), vehicle_hazards(world, "jeep")
    assert van[50, 80] and not jeep[50, 80] and not van[50, 20]
    both = hazard_map(world, ("jeep", "vw_van"))
    assert np.array_equal(both.mask, van | jeep)
    # 10 m on the flat, then 10 m up the slope: about 10 m of hazard on the segment
    assert both.length_m((10.0, 20.0), (30.0, 20.0)) == pytest.approx(10.0, abs=1.0)
    assert both.length_m((2.0, 5.0), (18.0, 5.0)) == 0.0


def test_the_hazard_rule_rejects_queries_that_cross_too_little_hazard():
    maps = SimpleNamespace(world="open", grid=GridSpec((0.0, 0.0), RES, (100, 100)),
                           occupancy=np.zeros((100, 100), np.uint8))
    mask = np.zeros((100, 100), bool)
    mask[:, 48:52] = True  # a 1.6 m band at x = 19.2–20.8 m
    band = HazardMap(maps.grid, mask)
    cfg = ExperimentsConfig(eval_distance_m=(10.0, 20.0), eval_min_hazard_m=1.0)
    draw = draw_random_queries(maps, 5, cfg, seed=1, vehicle="jeep", hazards=band, margin_m=2.0)
    assert draw.rejected["hazard"] > 0
    for q in draw.queries:
        assert band.length_m(q.start, q.goal) >= 1.0
    # every candidate is recorded with its fate, in the order drawn
    assert len(draw.tried) == draw.candidates
    fates = [fate for _, _, fate in draw.tried]
    assert {r: fates.count(r) for r in draw.rejected} == draw.rejected
    assert [(s, g) for s, g, fate in draw.tried if fate == "kept"] == \
        [(q.start, q.goal) for q in draw.queries]
