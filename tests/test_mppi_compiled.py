"""MPPI's compiled backend (dgt_lib.navigation.control.mppi_compiled) against the numpy reference:
the same commands to the bit, call after call, so closed-loop trials do not depend on it."""

import dataclasses
import math

import numpy as np
import pytest

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.navigation.control.mppi import MPPIController
from dgt_lib.navigation.control.mppi_config import vehicle_footprint


def s_curve(length=60.0, amplitude=4.0, wavelength=40.0):
    x = np.linspace(0.0, length, 300)
    k = 2 * np.pi / wavelength
    return np.stack([x, amplitude * np.sin(k * x), np.arctan(amplitude * k * np.cos(k * x))], 1)


def trees(path, clearance_m=3.0, n=300):
    """An occupancy grid with random occupied cells kept ``clearance_m`` off the path."""
    grid = GridSpec((-20.0, -40.0), 0.4, (200, 300))
    occ = np.zeros(grid.shape, np.uint8)
    rng = np.random.default_rng(0)
    r, c = rng.integers(0, grid.height, n), rng.integers(0, grid.width, n)
    X, Y = grid.cell_to_xy(r, c)
    keep = np.abs(Y - np.interp(X, path[:, 0], path[:, 1])) > clearance_m
    occ[r[keep], c[keep]] = 1
    return occ, grid


def costs(grid, n_headings=8, seed=1):
    """A directional costmap (K, H, W) of random costs in [0, 1): every cell and layer
    different, so a wrong cell or heading shows in the costs."""
    return np.random.default_rng(seed).random((n_headings, *grid.shape), np.float32)


def lockstep(cfg, calls, vehicle="mercedes_van", path=None, with_occupancy=True, speed=2.0,
             with_costmap=False):
    """Drive both backends side by side on a point-mass plant from the same states;
    yield (call, numpy controller, compiled controller, their two commands). With
    ``with_costmap`` the calls with an occupancy grid get a directional costmap too."""
    spec = get_vehicle(vehicle)
    path = s_curve() if path is None else path
    occ, grid = trees(path)
    cost = costs(grid) if with_costmap else None
    ctrls = [MPPIController.from_vehicle(spec, cfg, seed=3, backend=b)
             for b in ("numpy", "compiled")]
    for c in ctrls:
        c.set_path(path)
    x, y, yaw, v = float(path[0, 0]), float(path[0, 1]) + 0.5, float(path[0, 2]), speed
    for i in range(calls):
        o = (occ, grid, cost) if with_occupancy and i % 3 != 2 else (None, None, None)
        ref, fast = (c.compute((x, y, yaw), v, *o) for c in ctrls)
        yield i, *ctrls, ref, fast
        v_cmd, w_cmd = ref
        x += v_cmd * math.cos(yaw) * cfg.model_dt
        y += v_cmd * math.sin(yaw) * cfg.model_dt
        yaw += w_cmd * cfg.model_dt
        v = 0.8 * v + 0.2 * v_cmd


def assert_same_calls(cfg, calls, **kw):
    for i, numpy_ctrl, compiled_ctrl, ref, fast in lockstep(cfg, calls, **kw):
        assert fast == ref, f"call {i}: compiled {fast} ≠ numpy {ref}"
        np.testing.assert_array_equal(compiled_ctrl.optimal_sequence,
                                      numpy_ctrl.optimal_sequence, err_msg=f"call {i}")
        np.testing.assert_array_equal(compiled_ctrl.optimal_trajectory,
                                      numpy_ctrl.optimal_trajectory, err_msg=f"call {i}")
    return numpy_ctrl


def with_footprint(cfg, vehicle="mercedes_van"):
    return dataclasses.replace(cfg, **vehicle_footprint(get_vehicle(vehicle)))


def test_compiled_backend_gives_the_reference_commands_to_the_bit_along_a_whole_path():
    # Nav2's sizes, three footprint circles, trees near the path, the goal critic at the end
    cfg = with_footprint(MPPIConfig())
    ctrl = assert_same_calls(cfg, 330)
    pose = (ctrl.optimal_trajectory[0, 0], ctrl.optimal_trajectory[0, 1])
    ref = ctrl._reference()
    assert ref.remaining_m(ref.update_progress(*pose)) < cfg.goal_radius_m  # the goal critic ran


@pytest.mark.parametrize("changes", [
    # an odd batch, a horizon the scoring stride does not divide, reversing allowed,
    # no smoothing, one circle on the pose
    dict(batch_size=257, time_steps=31, path_point_step=3, v_min=-1.0, smoothing_window=1,
         footprint_offsets_m=(0.0,)),
    # the speed loop without lag, a tight collision radius and a lateral limit that binds
    dict(batch_size=64, speed_time_constant_s=0.0, collision_radius_m=0.3,
         inflation_radius_m=0.8, lateral_accel_max=0.5),
])
def test_compiled_backend_matches_the_reference_for_other_settings(changes):
    assert_same_calls(dataclasses.replace(with_footprint(MPPIConfig()), **changes), 60,
                      vehicle="jeep", speed=0.0)


def test_compiled_backend_matches_the_reference_when_a_sample_leaves_the_map():
    # a path along the grid's edge: rollouts land on the occupied ring around the map
    x = np.linspace(-18.0, 30.0, 200)
    edge = np.stack([x, np.full_like(x, -39.0), np.zeros_like(x)], 1)
    assert_same_calls(with_footprint(MPPIConfig(batch_size=200)), 40, path=edge)


def test_an_unknown_backend_is_refused():
    with pytest.raises(ValueError, match="backend"):
        MPPIController(MPPIConfig(), wheelbase_m=2.5, max_steer_rad=0.6, backend="cuda")


@pytest.mark.parametrize("changes", [
    dict(terrain_weight=0.05),  # the planner's β = 150: costs up to 151 × 0.05
    dict(terrain_weight=4.0, terrain_beta=0.0, batch_size=257, time_steps=31,
         footprint_offsets_m=(0.0,)),
])
def test_compiled_backend_matches_the_reference_with_the_terrain_critic(changes):
    cfg = dataclasses.replace(with_footprint(MPPIConfig(batch_size=400)), **changes)
    assert_same_calls(cfg, 90, with_costmap=True)


def test_compiled_terrain_critic_matches_when_a_sample_leaves_the_map():
    # a path along the grid's edge: body centres off the map read the edge cells
    x = np.linspace(-18.0, 30.0, 200)
    edge = np.stack([x, np.full_like(x, -39.0), np.zeros_like(x)], 1)
    cfg = dataclasses.replace(with_footprint(MPPIConfig(batch_size=200)), terrain_weight=0.05)
    assert_same_calls(cfg, 40, path=edge, with_costmap=True)


def test_compiled_backend_matches_the_reference_with_the_robust_controller():
    # the breakaway model lives in both rollouts, the roll limit acts after them: the
    # commands with every such field on are the same in both backends
    from dgt_lib.core.controller import ROBUST

    every = {**ROBUST, "ancillary_fraction": 0.1}
    assert_same_calls(with_footprint(dataclasses.replace(MPPIConfig(batch_size=200), **every)),
                      30, speed=0.3)
