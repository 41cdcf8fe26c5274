"""MPPI's terrain critic (ours; off by default): every rollout pays the directional
costmap at its body centre and heading, C(1 + βC), so the vehicle keeps to the cheap side
of terrain the plan runs beside (dgt_lib.navigation.control.critics.terrain_critic)."""

import dataclasses
import math

import numpy as np
import pytest

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.core.geometry import GridSpec, nearest_heading_bin
from dgt_lib.navigation.control.bicycle import KinematicBicycle, simulate_tracking
from dgt_lib.navigation.control.critics import heading_bins, terrain_table
from dgt_lib.navigation.control.mppi import MPPIController

WHEELBASE, MAX_STEER = 2.46, math.radians(35.0)  # the jeep
GRID = GridSpec((-10.0, -20.0), 0.4, (100, 200))
FAST = MPPIConfig(batch_size=300)
ON = dataclasses.replace(FAST, terrain_weight=10.0, terrain_beta=0.0)


def straight(length=40.0):
    x = np.linspace(0.0, length, 81)
    return np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)


def side_slope(boundary_y=-0.8):
    """A slope beside the path, costly for the heading that crosses it the wrong way: for
    headings east (layers 7, 0, 1 of 8) the cells north of ``boundary_y`` (a cell edge)
    cost 1, for headings west (3, 4, 5) those south of it; the path itself (y = 0) is
    costly eastbound."""
    _, Y = GRID.cell_centers()
    cost = np.zeros((8, *GRID.shape), np.float32)
    cost[[7, 0, 1]] = Y > boundary_y
    cost[[3, 4, 5]] = Y < boundary_y
    return cost


def drive(cfg, costmap, backend="compiled", start=(0.0, 0.5, 0.0), duration=10.0):
    """Closed loop along the straight path on a lagging, noisy bicycle, disturbed: the car
    starts 0.5 m north of the path (on the costly side)."""
    ctrl = MPPIController(cfg, wheelbase_m=WHEELBASE, max_steer_rad=MAX_STEER, seed=0,
                          backend=backend)
    plant = KinematicBicycle(WHEELBASE, MAX_STEER, pose=start, seed=1,
                             steer_noise_std_rad=0.02, steer_time_constant_s=0.15,
                             speed_time_constant_s=0.5)
    return simulate_tracking(ctrl, plant, straight(), duration,
                             occupancy=np.zeros(GRID.shape, np.uint8), grid=GRID,
                             costmap=costmap)


def middle(tr):
    """y [m] of the poses with 10 m < x < 30 m (start and goal behind and ahead)."""
    x, y = tr["pose"][:, 0], tr["pose"][:, 1]
    return y[(x > 10.0) & (x < 30.0)]


def end_y(tr):
    """y [m] where the car passes x = 35 m, before the goal critic turns on."""
    return float(tr["pose"][np.argmax(tr["pose"][:, 0] > 35.0), 1])


def paid(tr, costmap):
    """Mean cost C of the driven poses' body centres in the layer of their heading."""
    return paid_along(tr["pose"], costmap)


def paid_along(poses, costmap):
    """Mean cost C of (N, 3) rear-axle poses' body centres in their heading's layer."""
    x, y, yaw = np.asarray(poses, float).T
    cx, cy = x + 0.5 * WHEELBASE * np.cos(yaw), y + 0.5 * WHEELBASE * np.sin(yaw)
    r, c = GRID.xy_to_cell(cx, cy)
    return float(costmap[nearest_heading_bin(yaw, 8), r, c].mean())


def test_off_by_default_and_without_a_costmap_the_commands_are_the_plain_controllers():
    assert MPPIConfig().terrain_weight == 0.0  # the paper's controller
    cost = side_slope()
    plain = drive(FAST, None)
    for cfg, cm in ((FAST, cost), (ON, None)):
        tr = drive(cfg, cm)
        assert tr["v_cmd"].tolist() == plain["v_cmd"].tolist()
        assert tr["w_cmd"].tolist() == plain["w_cmd"].tolist()


@pytest.mark.parametrize("backend", ["numpy", "compiled"])
def test_the_critic_steers_a_disturbed_car_to_the_cheap_side_of_a_slope(backend):
    cost = side_slope()
    off, on = drive(FAST, cost, backend), drive(ON, cost, backend)
    # off: it tracks the path, on the costly side; on: it keeps south of the boundary
    assert np.all(middle(off) > -0.8)
    assert middle(on).mean() < -0.8 and -2.0 < middle(on).min() and middle(on).max() < -0.4
    assert paid(on, cost) < 0.5 * paid(off, cost)
    assert on["pose"][:, 0].max() > 35.0  # it still drives on along the path,
    assert end_y(on) < -0.8 < end_y(off)  # and ends the stretch on the cheap side


def test_the_chosen_sequence_pays_less_of_the_costmap():
    # called from a disturbed pose on the costly side (the warm start settling over ten
    # calls), the sequence MPPI chooses is predicted to cross to the cheap side
    cost, occ = side_slope(), np.zeros(GRID.shape, np.uint8)
    chosen = {}
    for cfg in (FAST, ON):
        ctrl = MPPIController(cfg, wheelbase_m=WHEELBASE, max_steer_rad=MAX_STEER, seed=0)
        ctrl.set_path(straight())
        for _ in range(10):
            ctrl.compute((5.0, 0.5, 0.0), 4.0, occ, GRID, cost)
        chosen[cfg.terrain_weight] = paid_along(ctrl.optimal_trajectory, cost)
    assert chosen[ON.terrain_weight] < 0.5 * chosen[0.0]


def test_the_critic_reads_the_layer_of_the_heading():
    # the same slope with its layers swapped (west ↔ east): now the north side is cheap
    north = drive(ON, np.roll(side_slope(boundary_y=0.8), 4, axis=0))
    assert middle(north).mean() > 0.8 and middle(north).min() > 0.4 and end_y(north) > 0.8


def test_heading_bins_are_the_nearest_heading_and_the_table_amplifies_like_the_planner():
    yaw = np.random.default_rng(0).uniform(-12.0, 12.0, 5000).astype(np.float32)
    frac = np.mod(yaw.astype(np.float64) / (2 * np.pi / 8), 1.0)
    clear = np.abs(frac - 0.5) > 1e-4  # away from the ties between two headings
    np.testing.assert_array_equal(heading_bins(yaw, 8)[clear],
                                  nearest_heading_bin(yaw.astype(np.float64), 8)[clear])
    c = np.array([[[0.0, 0.1, 1.0]]], np.float32)
    table = terrain_table(c, dataclasses.replace(FAST, terrain_beta=150.0))
    np.testing.assert_allclose(table.ravel(), [0.0, 0.1 * 16.0, 151.0], rtol=1e-6)
    with pytest.raises(ValueError, match="K, H, W"):
        terrain_table(c[0], FAST)


def test_a_costmap_must_sit_on_the_occupancy_grid_and_weights_are_checked():
    ctrl = MPPIController(ON, wheelbase_m=WHEELBASE, max_steer_rad=MAX_STEER)
    ctrl.set_path(straight())
    with pytest.raises(ValueError, match="grid"):
        ctrl.compute((0.0, 0.0, 0.0), 1.0, costmap=side_slope())
    with pytest.raises(ValueError, match="grid"):
        ctrl.compute((0.0, 0.0, 0.0), 1.0, np.zeros(GRID.shape), GRID,
                     costmap=side_slope()[:, :50])
    with pytest.raises(ValueError, match="terrain_weight"):
        MPPIConfig(terrain_weight=-1.0)
