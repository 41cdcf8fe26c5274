"""Occupancy and the slope-based baseline on the real experiment worlds (smoke survey)."""

import numpy as np
import pytest
from scipy import ndimage

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.mapping.baselines import SlopeModel, slope_costmap
from dgt_lib.mapping.occupancy import FREE, occupancy_map
from dgt_lib.stages.costmaps import ensure_tau_s, world_bev
from dgt_lib.world.terrain import get_world
from dgt_lib.world.worlds import polyline_distance

PROFILE = get_profile("smoke")


@pytest.fixture(scope="module")
def maps(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(artifacts.DATA_ENV_VAR, str(tmp_path_factory.mktemp("data")))
        tau = ensure_tau_s(PROFILE)
        yield {name: world_bev(name, PROFILE, progress=False)[0] for name in ("hill", "ridge")}, tau


def _route_core(bev, route, within_m=1.5):
    x, y = bev.grid.cell_centers()
    d = polyline_distance(np.stack([x.ravel(), y.ravel()], 1), route)[0].reshape(x.shape)
    return (d <= within_m) & bev.observed


def test_occupancy_marks_trees_but_not_the_steep_section_or_the_ridge(maps):
    bevs, tau = maps
    for name in ("hill", "ridge"):
        world, bev = get_world(name, PROFILE), bevs[name]
        occ = occupancy_map(bev, tau)
        for route in world.routes.values():  # steep Route B, sharp ridge crossing …
            assert (occ[_route_core(bev, route)] == FREE).all(), name
        # a tree's crown shows as a dome ringed by steep or unobserved cells: no free path
        # leads from open ground to its trunk
        islands, _ = ndimage.label(occ == FREE)
        open_ground = np.bincount(islands.ravel())[1:].argmax() + 1
        for tx, ty, _, _ in world.trees:
            r, c = bev.grid.xy_to_cell(tx, ty)
            assert islands[r, c] != open_ground, f"tree at ({tx:.0f}, {ty:.0f}) is reachable"
    assert tau < np.tan(np.radians(60.0))  # the hill's 60° cliffs are occupied


def test_slope_map_of_carla_cola_costs_more_uphill_on_route_b(maps):
    bevs, _ = maps
    hill, bev = get_world("hill", PROFILE), bevs["hill"]
    climb = np.radians(get_vehicle("carla_cola").max_climb_deg)
    cola = SlopeModel(theta0=0.0, theta_min=-0.8, theta_max=float(climb), p_u=2.0, p_d=2.0)
    sub = bev.crop(slice(100, 220), slice(40, 110))  # around the steep section (x≈30, y≈50–75)
    cost = slope_costmap(sub, [cola], 8, progress=False)[0]
    bottom, top = (np.asarray(hill.landmarks[n]) for n in ("B_steep_bottom", "B_steep_top"))
    pts = bottom + np.linspace(0.3, 0.7, 9)[:, None] * (top - bottom)
    r, c = sub.grid.xy_to_cell(pts[:, 0], pts[:, 1])
    uphill, downhill = cost[2][r, c].mean(), cost[6][r, c].mean()  # north vs south
    assert uphill > 0.9 and downhill < uphill - 0.4
