"""The ``eval_hazard`` world: the eval world plus V-ditches sized by the jeep's spec, whose
hazard statistics meet the target written in docs/worlds.md before any method ran on it."""

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

from dgt_lib.core.config import PROFILE_NAMES, get_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.experiments import experiment_world
from dgt_lib.evaluation.hazards import (
    HazardMap,
    bumper_sag,
    hazard_map,
    vehicle_hazards,
)
from dgt_lib.world.terrain import (
    BUMPER_RAISE_M,
    EXTRA_WORLD_NAMES,
    HILL_STEEP_DEG,
    WORLD_NAMES,
    add_ditches,
    ditch_parameters,
    get_world,
)
from dgt_lib.world.worlds import from_heightmap

SMOKE = get_profile("smoke")
STUDIES = str(Path(__file__).resolve().parents[1] / "studies")
if STUDIES not in sys.path:  # the query rule's line statistics live in its study
    sys.path.append(STUDIES)
line_stats = importlib.import_module("query_rule").line_stats
JEEP = get_vehicle("jeep")


def v_ditch(depth_m: float, flank_deg: float, cols: int = 150, rows: int = 60):
    """A straight V-ditch across a flat map along y, its bottom at x = 30 m."""
    x = (np.arange(cols) + 0.5) * 0.4
    profile = depth_m - np.clip(depth_m - np.abs(x - 30.0) * np.tan(np.radians(flank_deg)),
                                0.0, None)
    return from_heightmap(np.tile(profile, (rows, 1)), 0.4, name="ditch")


def test_bumper_sag_is_zero_on_a_plane_and_twice_the_flank_in_a_v():
    # on any plane the ground ahead lies on the wheels' line: nothing to dig into
    r, c = np.mgrid[0:40, 0:40]
    plane = 0.3 * c * 0.4 - 0.1 * r * 0.4
    np.testing.assert_allclose(bumper_sag(plane, 0.4, 2.4, 0.8)[6:-6, 6:-6], 0.0, atol=1e-12)
    # (off the map the edge repeats: no plane there)
    # front wheels at the bottom of a V of slope g, rear wheels 2.4 m up the near flank:
    # the far wall 0.8 m ahead stands 2·g·0.8 above the line through the wheels
    g = 0.4
    v = np.tile(np.abs(np.arange(60) - 30) * 0.4 * g, (20, 1))
    assert bumper_sag(v, 0.4, 2.4, 0.8)[10, 30] == pytest.approx(2 * g * 0.8)
    # a crest is no sag (driven along it, level; across it, the ground falls away)
    assert bumper_sag(-v, 0.4, 2.4, 0.8)[10, 30] <= 0.0


def test_ditches_are_jeep_hazards_only_through_its_bumper_and_leave_the_occupancy_free():
    par = ditch_parameters("jeep")
    for depth, flank in zip(par["depth_m"], par["flank_deg"], strict=True):
        w = v_ditch(depth, flank)
        # gentler than Route B's 26°, the steepest terrain the occupancy rule keeps free
        assert w.slope_deg().max() < HILL_STEEP_DEG
        assert not vehicle_hazards(w, "jeep").any()  # no slope or crest the jeep fails
        bottom = vehicle_hazards(w, "jeep", bumpers=True)[:, 70:80]  # x = 28–32 m
        assert bottom.any(axis=1).all()  # every row: the bottom stops its bumper


def test_ditch_sizes_follow_the_jeeps_spec():
    par = ditch_parameters("jeep")
    overhang = 0.5 * (JEEP.length_m - JEEP.wheelbase_m)
    least = (JEEP.ground_clearance_m + BUMPER_RAISE_M) / (2 * overhang)  # tan φ that digs in
    lo, hi = np.tan(np.radians(par["flank_deg"]))
    assert lo == pytest.approx(1.5 * least) and lo < hi <= np.tan(np.radians(25.5))
    assert par["depth_m"] == pytest.approx((2 * JEEP.ground_clearance_m,
                                            3 * JEEP.ground_clearance_m))


def test_the_hazard_constant_is_the_simulated_bumper():
    # the bumpers' underside sits BUMPER_RAISE_M above the belly's in the MuJoCo model
    from dgt_lib.world.mujoco_model import build_model

    m = build_model(v_ditch(0.5, 20.0), JEEP)
    geom = {name: m.geom(name) for name in ("belly", "bumper_front")}
    bottom = {k: g.pos[2] - g.size[2] for k, g in geom.items()}
    assert bottom["bumper_front"] - bottom["belly"] == pytest.approx(BUMPER_RAISE_M)


def test_eval_hazard_is_the_eval_world_plus_ditches_and_no_default_builds_it():
    assert EXTRA_WORLD_NAMES == ("eval_hazard",) and "eval_hazard" not in WORLD_NAMES
    ev, hz = get_world("eval", SMOKE), get_world("eval_hazard", SMOKE)
    assert hz.grid == ev.grid and np.array_equal(hz.trees, ev.trees)
    diff = hz.heights.astype(np.float64) - ev.heights
    untouched = np.isclose(diff - np.median(diff), 0.0, atol=1e-4)
    # the ditches and their levelled aprons change some ground, the rest is eval's
    assert 0.1 < untouched.mean() < 0.9
    # Experiment 3 keeps its world unless asked
    assert experiment_world("experiment3", SMOKE) == "eval"
    assert experiment_world(
        "experiment3", SMOKE.with_overrides({"experiments.eval_hazard_world": True})
    ) == "eval_hazard"
    assert experiment_world("experiment1", SMOKE.with_overrides(
        {"experiments.eval_hazard_world": True})) == "hill"


def test_the_hazard_world_reruns_experiment3_only():
    # Experiments 1 and 2 never drive on eval_hazard: their stored trials stay valid
    from dgt_lib.stages.experiments import experiment_config

    hazard = SMOKE.with_overrides({"experiments.eval_hazard_world": True})
    for name in ("experiment1", "experiment2"):
        assert experiment_config(name, hazard) == experiment_config(name, SMOKE)
    assert experiment_config("experiment3", hazard) != experiment_config("experiment3", SMOKE)


def test_a_ditch_at_both_ends_of_its_range_stops_the_jeep_at_the_trials_speed():
    # the premise, in MuJoCo: driven straight at 5 m/s into the gentlest-shallowest and the
    # steepest-deepest ditch, the jeep stays with its front wheels in it
    from dgt_lib.navigation.drive import drive_straight
    from dgt_lib.world.simulator import Simulator

    par = ditch_parameters("jeep")
    for depth, flank in zip(par["depth_m"], par["flank_deg"], strict=True):
        sim = Simulator(v_ditch(depth, flank), JEEP)
        try:
            tr = drive_straight(sim, 20.0, 12.0, 0.0, speed_mps=5.0, duration_s=6.0)
        finally:
            sim.close()
        assert 27.0 < tr.position[-1, 0] < 30.0, (depth, flank, tr.position[-1])
        assert abs(tr.speed_mps[-1]) < 0.25


@pytest.mark.parametrize("profile", PROFILE_NAMES)
def test_eval_hazard_meets_its_written_target_on_every_profile(profile):
    # docs/worlds.md, fixed before any trial: ≥ 1 % of cells jeep hazards and ≥ 40 % of the
    # lines Experiment 3's (unchanged) query rule keeps cross one; the eval world has neither
    prof = get_profile(profile)
    ex = prof.experiments
    shares = {}
    for name in ("eval", "eval_hazard"):
        world = get_world(name, prof)
        jeep = HazardMap(world.grid, vehicle_hazards(world, "jeep", bumpers=True))
        st = line_stats(hazard_map(world, ("jeep", "vw_van")), jeep, ex.eval_distance_m,
                        ex.eval_min_hazard_m, prof.seed, candidates=1500)
        shares[name] = (jeep.fraction, st.kept_crossing)
    assert shares["eval_hazard"][0] >= 0.01 and shares["eval_hazard"][1] >= 0.40
    assert shares["eval"][0] < 0.01 and shares["eval"][1] < 0.40


def test_ditches_are_drawn_from_their_own_stream():
    flat = from_heightmap(np.zeros((100, 100)), 0.4, name="flat")
    a, b = add_ditches(flat, 3, 5, "a"), add_ditches(flat, 3, 5, "b")
    assert np.array_equal(a.heights, b.heights)
    assert not np.array_equal(a.heights, add_ditches(flat, 3, 6, "c").heights)


def test_ditches_sit_on_level_ground_so_their_flanks_stay_free_on_a_slope():
    # on a 0.12 m/m hillside (the eval world's typical grade) a ditch cut straight in would
    # have one flank at tan φ + 0.12 > tan 26°, occupied; on its levelled apron no cell
    # is steeper than the flank itself, and the ditch keeps its full depth
    x = (np.arange(250) + 0.5) * 0.4
    hillside = np.tile(0.12 * x, (250, 1))
    world = add_ditches(from_heightmap(hillside, 0.4, name="hillside"), 1, 3, "hillside")
    slope = np.hypot(*np.gradient(world.heights.astype(np.float64), 0.4))
    flank_hi = np.tan(np.radians(ditch_parameters("jeep")["flank_deg"][1]))
    assert slope.max() <= flank_hi + 0.01 < np.tan(np.radians(HILL_STEEP_DEG))
    assert vehicle_hazards(world, "jeep", bumpers=True).any()  # still stops the jeep
    assert not vehicle_hazards(world, "jeep").any()  # through its bumper only
