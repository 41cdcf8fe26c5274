"""The driven cost: a trajectory pays the layer of the direction it moved in."""

import numpy as np

from dgt_lib.core.geometry import GridSpec
from dgt_lib.evaluation.driven_cost import driven_cost

GRID = GridSpec((0.0, 0.0), 1.0, (20, 20))


def _slope_costmap() -> np.ndarray:
    # a slope rising to the north: climbing north (layer 2 of 8) costs 1, descending south
    # (layer 6) 0, across it (0 and 4) 0.5
    cost = np.full((8, 20, 20), 0.5, np.float32)
    cost[2], cost[6] = 1.0, 0.0
    return cost


def _straight(start, end, n=30, stand=0):
    xy = np.linspace(start, end, n)
    xy = np.vstack([np.repeat(xy[:1], stand, axis=0), xy])  # standing samples first
    t = np.arange(len(xy)) * 0.1
    return np.column_stack([t, xy, np.zeros(len(xy))])


def test_the_same_ground_costs_by_the_direction_driven():
    cost = _slope_costmap()
    assert driven_cost(_straight((10, 2), (10, 18)), cost, GRID) == 1.0   # up the slope
    assert driven_cost(_straight((10, 18), (10, 2)), cost, GRID) == 0.0   # down it
    assert driven_cost(_straight((2, 10), (18, 10)), cost, GRID) == 0.5   # across it


def test_standing_still_neither_pays_nor_picks_a_heading():
    cost = _slope_costmap()
    # jitter of a standing truck (1 cm) must not be read as travel in some direction
    standing = _straight((10, 2), (10, 2.01), n=40)
    assert np.isnan(driven_cost(standing, cost, GRID))
    assert driven_cost(_straight((10, 18), (10, 2), stand=50), cost, GRID) == 0.0
