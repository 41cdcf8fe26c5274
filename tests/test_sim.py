"""The simulator: terrain round trip, state reporting, end reasons, rendering."""

import math

import mujoco
import numpy as np
import pytest
from scipy import ndimage

from dgt_lib.core.camera import CameraIntrinsics
from dgt_lib.core.vehicles import UnknownVehicleError, get_vehicle
from dgt_lib.navigation.drive import drive_straight, follow_path
from dgt_lib.world.mujoco_model import CAMERA, MAX_DEPTH_M
from dgt_lib.world.simulator import Simulator, look_at
from dgt_lib.world.speed_control import SpeedController
from dgt_lib.world.terrain import get_world
from dgt_lib.world.worlds import from_heightmap


@pytest.fixture(scope="module")
def bumpy():
    rng = np.random.default_rng(1)
    h = ndimage.gaussian_filter(rng.standard_normal((90, 70)), 8) * 12.0  # slopes up to ~20°
    colors = np.zeros((90, 70, 3), np.float32)
    colors[:, :35] = (0.8, 0.2, 0.1)  # west half red
    colors[:, 35:] = (0.1, 0.3, 0.9)  # east half blue
    return from_heightmap(h, 0.4, origin=(-5.0, 3.0), colors=colors,
                          trees=[(10.0, 30.0, 0.3, 6.0)])


def test_terrain_in_simulator_matches_the_array(bumpy):
    bumpy = from_heightmap(bumpy.heights, 0.4, origin=(-5.0, 3.0))  # no tree in the way
    sim = Simulator(bumpy, "jeep")
    m, d = sim.model, sim.data
    mujoco.mj_forward(m, d)
    X, Y = bumpy.grid.cell_centers()
    rng = np.random.default_rng(0)
    rows, cols = rng.integers(1, 89, 200), rng.integers(1, 69, 200)  # (rays miss exact edges)
    geomid = np.zeros(1, np.int32)
    got = []
    for r, c in zip(rows, cols, strict=True):
        start = np.array([X[r, c], Y[r, c], 50.0])
        dist = mujoco.mj_ray(m, d, start, np.array([0, 0, -1.0]), None, 1, -1, geomid)
        assert geomid[0] == m.geom("terrain").id
        got.append(50.0 - dist)
    assert np.allclose(got, bumpy.heights[rows, cols], atol=2e-3)


def test_reset_settles_on_the_ground(bumpy):
    sim = Simulator(bumpy, "mercedes_van")
    st = sim.reset(10.0, 15.0, 1.0)
    assert st.time_s == 0.0 and st.done_reason is None
    assert st.wheel_contacts.all() and not st.chassis_contact
    assert abs(st.speed_mps) < 0.05
    assert math.isclose(st.yaw, 1.0, abs_tol=0.03)
    ground = bumpy.height_at(st.position[0], st.position[1])
    assert 0.0 < st.position[2] - ground < 1.0


def test_api_misuse_is_a_clear_error(bumpy):
    with pytest.raises(UnknownVehicleError, match="valid vehicles"):
        Simulator(bumpy, "bicycle")
    sim = Simulator(bumpy, "jeep")
    with pytest.raises(RuntimeError, match="reset"):
        sim.step(speed_cmd_mps=5.0)
    sim.reset(0.0, 10.0, 0.0)
    with pytest.raises(ValueError, match="exactly one"):
        sim.step(speed_cmd_mps=5.0, throttle=0.5)
    with pytest.raises(ValueError, match="exactly one"):
        sim.step()


@pytest.mark.parametrize("pose", [(math.nan, 10.0, 0.0), (0.0, math.inf, 0.0),
                                  (0.0, 10.0, math.nan)])
def test_a_non_finite_reset_pose_is_a_value_error_naming_it(bumpy, pose):
    sim = Simulator(bumpy, "jeep")
    with pytest.raises(ValueError, match="Simulator.reset needs finite numbers"):
        sim.reset(*pose)


@pytest.mark.parametrize("command", [{"speed_cmd_mps": 5.0, "steer": math.nan},
                                     {"speed_cmd_mps": math.nan},
                                     {"throttle": math.inf},
                                     {"throttle": 0.5, "brake": math.nan},
                                     {"speed_cmd_mps": 5.0, "duration_s": math.nan}])
def test_a_non_finite_command_is_a_value_error_not_ignored(bumpy, command):
    """NaN steering used to be zeroed by MuJoCo without a word: the run went straight on."""
    sim = Simulator(bumpy, "jeep")
    sim.reset(0.0, 10.0, 0.0)
    before = sim.state
    name = next(k for k, v in command.items() if not math.isfinite(v))
    with pytest.raises(ValueError, match=name):
        sim.step(**command)
    assert sim.state is before  # nothing was simulated


def test_divergence_ends_the_run_without_raising(bumpy):
    sim = Simulator(bumpy, "jeep")
    sim.reset(0.0, 10.0, 0.0)
    sim.data.qvel[:] = np.nan
    st = sim.step(speed_cmd_mps=5.0)
    assert st.done_reason == "diverged"
    assert sim.step(speed_cmd_mps=5.0).done_reason == "diverged"  # and stays ended


def test_a_state_the_last_physics_step_made_non_finite_ends_the_run(bumpy, monkeypatch):
    """MuJoCo checks the state before a step; a coordinate that the last step of a control
    period turned infinite is caught by the kit, not reported as a pose."""
    sim = Simulator(bumpy, "jeep")
    sim.reset(0.0, 10.0, 0.0)
    step = mujoco.mj_step

    def blow_up(m, d, nstep=1):
        step(m, d, nstep=nstep)
        d.qpos[0] = np.inf

    monkeypatch.setattr(mujoco, "mj_step", blow_up)
    st = sim.step(speed_cmd_mps=5.0)
    assert st.done_reason == "diverged" and np.isfinite(st.position).all()


def test_flipped_and_off_map_end_the_run():
    flat = from_heightmap(np.zeros((60, 60)), 0.4)
    sim = Simulator(flat, "jeep")
    sim.reset(12.0, 12.0, 0.0)
    sim.data.qpos[2] += 2.0
    sim.data.qpos[3:7] = [0.0, 1.0, 0.0, 0.0]  # upside down
    for _ in range(50):
        st = sim.step(throttle=0.0)
    assert st.flipped and st.done_reason == "flipped"
    tr = drive_straight(sim, 12.0, 12.0, 0.0, duration_s=20.0)
    assert tr.end_reason == "off_map" and tr.position[-1, 0] > 23.0


def test_trees_collide_and_immobilize(bumpy):
    sim = Simulator(bumpy, "jeep")
    # The tree at (10, 30) stands 10 m ahead.
    tr = drive_straight(sim, 0.0, 30.0, 0.0, duration_s=12.0)
    st = sim.state
    assert st.tree_contact
    assert tr.position[:, 0].max() < 10.0
    assert st.immobilized_s > 3.0


def test_brakes_hold_on_a_slope():
    ramp = from_heightmap(np.tile(np.arange(100) * 0.4 * np.tan(np.radians(15)), (40, 1)), 0.4)
    sim = Simulator(ramp, "carla_cola")
    sim.reset(20.0, 8.0, 0.0)
    x0 = sim.state.position[0]
    for _ in range(100):
        st = sim.step(speed_cmd_mps=0.0)
    assert abs(st.position[0] - x0) < 0.05 and st.immobilized_s > 3.5


def test_speed_controller_feed_forward_counters_grade():
    ctl = SpeedController(get_vehicle("jeep"))
    flat = ctl(5.0, 5.0, 0.0, 0.04)
    ctl.reset()
    up = ctl(5.0, 5.0, math.radians(10), 0.04)
    ctl.reset()
    down = ctl(5.0, 5.0, math.radians(-20), 0.04)
    assert up[0] > flat[0] > 0.0 and flat[1] == up[1] == 0.0
    assert down[0] == 0.0 and down[1] > 0.0  # downhill: brakes


def test_same_inputs_same_trajectory():
    world = get_world("ridge", "smoke")
    path = np.array([[20.0, 25.0], [30.0, 38.0], [30.0, 55.0]])
    a = follow_path(Simulator(world, "vw_van"), path, max_time_s=8.0)
    b = follow_path(Simulator(world, "vw_van"), path, max_time_s=8.0)
    assert np.array_equal(a.position, b.position) and a.end_reason == b.end_reason


def test_onboard_rgbd_frame_matches_the_terrain(bumpy):
    sim = Simulator(bumpy, "jeep")
    sim.reset(0.0, 10.0, math.pi / 4)
    f = sim.render_rgbd()
    assert f.rgb.shape == (CAMERA.height, CAMERA.width, 3) and f.rgb.dtype == np.uint8
    assert f.depth.shape == (CAMERA.height, CAMERA.width) and f.depth.dtype == np.float32
    valid = np.isfinite(f.depth)
    assert valid.mean() > 0.3
    assert np.nanmax(f.depth) < MAX_DEPTH_M
    pts, _ = f.points_world()
    inside = bumpy.grid.contains(pts[:, 0], pts[:, 1])
    err = pts[inside, 2] - bumpy.height_at(pts[inside, 0], pts[inside, 1])
    assert np.median(np.abs(err)) < 0.02
    # The camera sits on the vehicle at its mount.
    v = get_vehicle("jeep")
    assert np.linalg.norm(f.position - sim.state.position) == pytest.approx(
        math.hypot(v.camera.forward_m, v.camera.up_m), abs=0.05)


def test_survey_rgbd_shows_the_colour_texture(bumpy):
    sim = Simulator(bumpy, "jeep")
    sim.reset(0.0, 10.0, 0.0)
    x0, x1, y0, y1 = bumpy.extent
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    f = sim.render_rgbd(look_at((cx, cy, 30.0), (cx, cy, 0.0)),
                        intrinsics=CameraIntrinsics(96, 96, math.radians(60)))
    pts, cols = f.points_world()
    r, c = bumpy.grid.xy_to_cell(pts[:, 0], pts[:, 1])
    ok = bumpy.grid.contains(pts[:, 0], pts[:, 1]) & (np.abs(c - 34.5) > 3)
    truth = bumpy.colors[r[ok], c[ok]]
    west = truth[:, 0] > 0.5
    assert west.any() and (~west).any()
    assert cols[ok][west, 0].mean() > cols[ok][west, 2].mean() + 0.2  # red where red
    assert cols[ok][~west, 2].mean() > cols[ok][~west, 0].mean() + 0.2  # blue where blue
    err = pts[:, 2] - bumpy.height_at(pts[:, 0], pts[:, 1])
    assert np.median(np.abs(err[bumpy.grid.contains(pts[:, 0], pts[:, 1])])) < 0.02


def test_look_at_points_the_camera_axis():
    pos, rot = look_at((0, 0, 10), (10, 0, 0))
    assert np.allclose(rot.T @ rot, np.eye(3), atol=1e-12)
    view = -rot[:, 2]
    assert np.allclose(view, np.array([1, 0, -1]) / math.sqrt(2))
    assert rot[2, 1] > 0  # image up is world up-ish


def test_pitch_and_roll_signs_on_a_slope():
    y_rising = np.tile((np.arange(60) * 0.4 * np.tan(np.radians(10)))[:, None], (1, 60))
    sim = Simulator(from_heightmap(y_rising, 0.4), "jeep")
    st = sim.reset(12.0, 12.0, 0.0)  # facing +x: the left (+y) side is uphill
    assert math.degrees(st.roll) == pytest.approx(10.0, abs=2.0)
    assert abs(math.degrees(st.pitch)) < 2.0
    st = sim.reset(12.0, 12.0, math.pi / 2)  # facing up the slope
    assert math.degrees(st.pitch) == pytest.approx(10.0, abs=2.0)


def test_reverse_speed_command():
    flat = from_heightmap(np.zeros((60, 200)), 0.4)
    tr = drive_straight(Simulator(flat, "carla_cola"), 60.0, 12.0, 0.0, speed_mps=-2.0,
                        duration_s=8.0)
    assert tr.speed_mps[-1] == pytest.approx(-2.0, abs=0.25)
    assert tr.position[-1, 0] < 50.0  # it went backwards (−x while facing +x)


def test_mujoco_s_log_of_a_diverging_simulation_goes_to_the_data_directory(tmp_path):
    """MuJoCo wrote MUJOCO_LOG.TXT into the current directory when a drive diverged."""
    import os
    import subprocess
    import sys

    script = (
        "import mujoco, numpy as np\n"
        "from dgt_lib.world.mujoco_model import build_model\n"
        "from dgt_lib.world.worlds import from_heightmap\n"
        "build_model(from_heightmap(np.zeros((40, 40), np.float32), 0.4), 'jeep')\n"
        "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><freejoint/>"
        "<geom size=\".1\"/></body></worldbody></mujoco>')\n"
        "d = mujoco.MjData(m); d.qvel[:] = 1e300; mujoco.mj_step(m, d)\n")
    cwd, data = tmp_path / "cwd", tmp_path / "data"
    cwd.mkdir()
    data.mkdir()
    env = {**os.environ, "DGT_DATA_DIR": str(data),
           "PYTHONPATH": os.pathsep.join(filter(None, [os.getcwd(),
                                                       os.environ.get("PYTHONPATH")]))}
    subprocess.run([sys.executable, "-c", script], cwd=cwd, env=env, check=True,
                   capture_output=True, timeout=120)
    assert not (cwd / "MUJOCO_LOG.TXT").exists()
    assert "QVEL" in (data / "MUJOCO_LOG.TXT").read_text()


def test_a_contact_means_what_its_pair_of_geom_kinds_says():
    """A wheel touches the terrain or a tree; the chassis counts on the terrain only; any
    contact with a tree is one; which geom comes first does not matter."""
    from dgt_lib.world.contacts import (
        CHASSIS,
        CHASSIS_ON_TERRAIN,
        MEANING,
        ON_TREE,
        OTHER,
        TERRAIN,
        TREE,
        WHEEL,
    )
    assert MEANING[WHEEL + 2][TERRAIN] == MEANING[TERRAIN][WHEEL + 2] == 1 << 2
    assert MEANING[TREE][WHEEL] == ON_TREE | 1
    assert MEANING[CHASSIS][TERRAIN] == CHASSIS_ON_TERRAIN
    assert MEANING[TREE][CHASSIS] == ON_TREE
    assert MEANING[WHEEL][CHASSIS] == MEANING[OTHER][WHEEL + 3] == 0
