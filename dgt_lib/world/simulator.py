"""MuJoCo simulation of one vehicle on one world: drive, sense, render RGB-D.

:class:`Simulator` wraps the MuJoCo model of :func:`~dgt_lib.world.mujoco_model.build_model`
(wheel motors follow ``τ = τ_max·(throttle − ω/ω_max)`` clamped to ±τ_max — a torque
limit and a speed cap in one; brakes are Coulomb friction on the wheel joints, so a
braked vehicle holds on a slope; drag is applied at control rate) and its data::

    from dgt_lib.world.simulator import Simulator
    sim = Simulator(world, "jeep")
    state = sim.reset(x, y, yaw)                 # settled on the ground, time 0
    state = sim.step(speed_cmd_mps=5.0, steer=0.2)   # 0.04 s, PID speed control
    frame = sim.render_rgbd()                    # dgt_lib.core.camera.RGBDFrame

Steering ``steer`` is normalised to [−1, 1] of the vehicle's maximum steering
angle (paper, Controller Integration). Physics runs at 8 ms; control at 25 Hz
(``CONTROL_DT_S``). A NaN state ends the run with ``done_reason = "diverged"``
instead of raising; other reasons: ``"flipped"``, ``"off_map"``.

Camera (:data:`~dgt_lib.world.mujoco_model.CAMERA`): 160 × 120 px, vertical field of
view 70°, mounted per vehicle (``VehicleSpec.camera``: forward, up, pitched down 20°);
depth is metric along the view axis and NaN beyond ``MAX_DEPTH_M`` = 40 m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import mujoco  # dgt_lib/__init__.py has set MUJOCO_GL=egl before this import
import numpy as np

from dgt_lib.core.camera import CameraIntrinsics, RGBDFrame
from dgt_lib.core.vehicle_spec import AIR_DENSITY_KGPM3, VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.world.contacts import CHASSIS, OTHER, TERRAIN, TREE, WHEEL, touching
from dgt_lib.world.mujoco_model import (
    BIT_TERRAIN,
    BIT_TREE,
    CAMERA,
    MAX_DEPTH_M,
    TIMESTEP_S,
    VEHICLE_GEOM_GROUP,
    WHEEL_NAMES,
    build_model,
)
from dgt_lib.world.speed_control import SpeedController
from dgt_lib.world.underside_gate import diverged, min_underside_gap
from dgt_lib.world.worlds import World

CONTROL_DT_S = 0.04  # control period [s] (25 Hz)
IMMOBILE_SPEED_MPS = 0.25  # below this horizontal speed the vehicle counts as immobile
FLIP_UP_Z = 0.3  # flipped when the chassis up-axis z-component drops below this
UNDERSIDE_MARGIN_M = 0.05  # belly/bumper collision tests run within this of the ground
GATE_PERIOD_S = 0.04  # time between two checks of that gap [s]: one per control period
GATE_STEPS = max(1, round(GATE_PERIOD_S / TIMESTEP_S))  # physics steps between two checks




EXACT_DEPTH_RESOLVE = (b"llvmpipe",)
"""OpenGL renderers (``GL_RENDERER`` substrings) whose multisampled depth equals the depth
drawn without multisampling, bit for bit (Mesa's llvmpipe: measured, and checked by
``tests/test_collect.py`` wherever the tests run on it)."""


class FrameRenderers(NamedTuple):
    """The OpenGL renderers of one frame size: ``rgb`` draws the colour image (with the
    model's multisampling, ``vis.quality.offsamples``), ``depth`` the depth image, without.
    A multisampled depth buffer is resolved differently by each OpenGL driver: on the hill
    world NVIDIA's depth differed from Mesa llvmpipe's by a median 1–30 mm and up to 7 m at
    edges; without multisampling by ≤ 0.1 mm on survey frames (median 5·10⁻⁵ m on an onboard
    one). On a renderer of :data:`EXACT_DEPTH_RESOLVE` the multisampled depth already is that
    depth, so ``depth`` is ``rgb`` there (a second context would double the terrain uploads:
    ~33 ms each, 14 more in a 100 s collection run)."""

    rgb: mujoco.Renderer
    depth: mujoco.Renderer

    @classmethod
    def create(cls, model: mujoco.MjModel, height: int, width: int,
               separate_depth: bool | None = None) -> FrameRenderers:
        """Renderers of ``height`` × ``width`` frames for ``model``; ``separate_depth``:
        whether depth gets its own context without multisampling (default: unless the
        model draws none or the OpenGL renderer is one of :data:`EXACT_DEPTH_RESOLVE`)."""
        rgb = mujoco.Renderer(model, height, width)
        samples = model.vis.quality.offsamples
        if separate_depth is None:
            separate_depth = samples > 0 and not any(
                name in opengl_renderer(rgb) for name in EXACT_DEPTH_RESOLVE)
        if not separate_depth:
            return cls(rgb, rgb)
        model.vis.quality.offsamples = 0  # read once, when the GL context is made
        try:
            depth = mujoco.Renderer(model, height, width)
        finally:
            model.vis.quality.offsamples = samples
        return cls(rgb, depth)

    def distinct(self) -> tuple[mujoco.Renderer, ...]:
        """Each renderer once (one when depth shares the colour one's context)."""
        return tuple(dict.fromkeys(self))

    def close(self) -> None:
        for r in self.distinct():
            r.close()


def opengl_renderer(renderer: mujoco.Renderer) -> bytes:
    """``GL_RENDERER`` of ``renderer``'s OpenGL context, e.g. ``b"llvmpipe (LLVM 15.0.7,
    256 bits)"`` or ``b"NVIDIA H100 80GB HBM3/PCIe/SSE2"``."""
    from OpenGL import GL

    renderer._gl_context.make_current()
    return GL.glGetString(GL.GL_RENDERER) or b""


def check_finite(where: str, **values: float | None) -> None:
    """Raise ValueError naming each argument of ``where`` that is not a finite number
    (NaN, ±inf); None passes. MuJoCo would otherwise index with NaN (an IndexError) or
    zero a NaN control silently (its bad-control warning)."""
    bad = [f"{name}={value!r}" for name, value in values.items()
           if value is not None and not math.isfinite(float(value))]
    if bad:
        raise ValueError(f"{where} needs finite numbers, got {', '.join(bad)}")


def immobile_time(immobile_s: float, speed_mps: float, dt_s: float,
                  threshold_mps: float = IMMOBILE_SPEED_MPS) -> float:
    """How long [s] a vehicle has been immobile after one more step of ``dt_s`` [s] at
    ``speed_mps`` [m/s]: ``immobile_s + dt_s`` while |speed| < ``threshold_mps``, else 0.

    The one immobility detector of the kit: the simulator's ``immobilized_s`` and the
    outcome rule of a trial (:mod:`dgt_lib.navigation.outcome`) both count with it."""
    return immobile_s + dt_s if abs(speed_mps) < threshold_mps else 0.0


def ackermann_angles(steer: float, vehicle: VehicleSpec) -> tuple[float, float]:
    """Left and right road-wheel angles [rad] for a normalised steer ∈ [−1, 1]:
    δ = steer·δ_max on the virtual centre wheel, R = L / tan δ, and
    δ_{l,r} = atan(L / (R ∓ T/2)) (positive = left turn)."""
    d = min(max(float(steer), -1.0), 1.0) * vehicle.max_steer_rad
    if abs(d) < 1e-6:
        return 0.0, 0.0
    L, T = vehicle.wheelbase_m, vehicle.track_m
    R = L / math.tan(d)
    return math.atan(L / (R - T / 2)), math.atan(L / (R + T / 2))


# ----------------------------------------------------------------------------- simulator


@dataclass
class VehicleState:
    """What the simulator reports after a step (world frame, SI units).

    position: (3,) chassis origin [m] (midway between the axles, wheel-centre height).
    yaw, roll, pitch [rad]: yaw in [0, 2π) from +x, pitch positive nose-up, roll
    positive left side up. velocity: (3,) [m/s]. speed_mps: signed speed along the
    heading. angular_rate: (3,) body-frame [rad/s]; yaw_rate its z about world up.
    wheel_contacts: (4,) bool, order fl, fr, rl, rr. chassis_contact: the body
    touches terrain. tree_contact: the vehicle touches a tree. immobilized_s: time
    continuously below IMMOBILE_SPEED_MPS. done_reason: None or "diverged",
    "flipped", "off_map".
    """

    time_s: float
    position: np.ndarray
    yaw: float
    roll: float
    pitch: float
    velocity: np.ndarray
    speed_mps: float
    yaw_rate: float
    angular_rate: np.ndarray
    wheel_contacts: np.ndarray
    chassis_contact: bool
    tree_contact: bool
    flipped: bool
    immobilized_s: float
    done_reason: str | None

    @property
    def done(self) -> bool:
        return self.done_reason is not None


class Simulator:
    """One vehicle on one world. ``reset`` before stepping; see the module docstring."""

    def __init__(self, world: World, vehicle: str | VehicleSpec, *,
                 camera: CameraIntrinsics = CAMERA):
        self.world = world
        self.vehicle = get_vehicle(vehicle)
        self.model = build_model(world, self.vehicle)
        self.data = mujoco.MjData(self.model)
        self._warnings = self.data.warning.number  # a live view: MuJoCo's warning counts
        self.camera = camera
        self.speed_controller = SpeedController(self.vehicle)
        m = self.model
        self._chassis = m.body("chassis").id
        self._terrain = m.geom("terrain").id
        self._chassis_geoms = np.array([m.geom(n).id for n in
                                        ("belly", "bumper_front", "bumper_rear", "body")])
        self._wheel_geoms = np.array([m.geom(f"wheel_{n}").id for n in WHEEL_NAMES])
        self._tree_geoms = np.array([i for i in range(m.ngeom)
                                     if (m.geom(i).name or "").startswith("tree")], int)
        kind = np.full(m.ngeom, OTHER, np.int64)
        kind[self._terrain], kind[self._tree_geoms], kind[self._chassis_geoms] = (
            TERRAIN, TREE, CHASSIS)
        kind[self._wheel_geoms] = WHEEL + np.arange(4)
        self._geom_kind = kind.tolist()  # read per contact in plain Python (contacts.py)
        # Underside sample points (chassis frame) for the collision gate, ≤ 0.4 m apart.
        v = self.vehicle
        half_w = 0.8 * v.track_m / 2
        xs = np.linspace(-v.length_m / 2, v.length_m / 2, int(np.ceil(v.length_m / 0.4)) + 1)
        ys = np.linspace(-half_w, half_w, int(np.ceil(2 * half_w / 0.4)) + 1)
        gx, gy = np.meshgrid(xs, ys)
        self._underside = np.stack([gx.ravel(), gy.ravel(),
                                    np.full(gx.size, v.ground_clearance_m - v.wheel_radius_m)], 1)
        self._underside_geoms = self._chassis_geoms[:3]  # belly and bumpers
        self._underside_aff = -1  # their conaffinity as last set (-1: not yet)
        self._z = world.heights.astype(np.float64)
        if min(self._z.shape) < 2:
            raise ValueError("a world needs at least 2 × 2 height cells")
        self._inv_res = 1.0 / world.resolution
        g = world.grid
        self._map = (*g.origin_xy, g.resolution, g.height, g.width)  # for _on_map
        self._x0 = world.grid.origin_xy[0] + 0.5 * world.resolution  # first cell centre
        self._y0 = world.grid.origin_xy[1] + 0.5 * world.resolution
        self._spin_dofs = np.array([m.joint(f"spin_{n}").dofadr[0] for n in WHEEL_NAMES])
        self._brake0 = m.dof_frictionloss[self._spin_dofs].copy()
        self._brake: float | None = None  # the brake as last applied (None: not yet)
        self._motors = np.array([m.actuator(f"motor_{n}").id for n in WHEEL_NAMES
                                 if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR,
                                                      f"motor_{n}") >= 0])
        self._steer = np.array([m.actuator("steer_fl").id, m.actuator("steer_fr").id])
        self._renderers: dict[tuple[int, int], FrameRenderers] = {}
        self._immobile_s = 0.0
        self._done: str | None = None
        self._state: VehicleState | None = None

    # -- control ---------------------------------------------------------------------------

    def reset(self, x: float, y: float, yaw: float, *, settle_s: float = 1.0) -> VehicleState:
        """Place the vehicle at (x, y) [m] heading ``yaw`` [rad], drop it onto the
        terrain, let it settle ``settle_s`` with brakes on, then set time to 0.

        Raises ValueError for a non-finite x, y, yaw or settle_s, or settle_s < 0. A
        pose off the map is allowed: the state's ``done_reason`` is then "off_map"."""
        check_finite("Simulator.reset", x=x, y=y, yaw=yaw, settle_s=settle_s)
        if settle_s < 0:
            raise ValueError(f"Simulator.reset needs settle_s ≥ 0 s, got {settle_s}")
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        v = self.vehicle
        c, s = math.cos(yaw), math.sin(yaw)
        fx, fy = np.meshgrid([-v.length_m / 2, 0, v.length_m / 2], [-v.width_m / 2, 0,
                                                                     v.width_m / 2])
        px, py = x + c * fx - s * fy, y + s * fx + c * fy
        ground = float(np.max(self.world.height_at(px, py)))
        d.qpos[0:3] = [x, y, ground + v.wheel_radius_m + 0.15]
        d.qpos[3:7] = [math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)]
        self.speed_controller.reset()
        self._immobile_s = 0.0
        self._done = None
        self._apply(0.0, 1.0, 0.0)
        self._gate_underside(force=True)
        mujoco.mj_step(m, d, nstep=max(1, int(round(settle_s / TIMESTEP_S))))
        d.time = 0.0
        mujoco.mj_forward(m, d)
        self._state = self._read_state()
        return self._state

    def _apply(self, throttle: float, brake: float, steer: float) -> None:
        d, m = self.data, self.model
        d.ctrl[self._motors] = min(max(float(throttle), -1.0), 1.0)
        brake = min(max(float(brake), 0.0), 1.0)
        if brake != self._brake:  # the wheels' friction changes only with the brake
            m.dof_frictionloss[self._spin_dofs] = self._brake0 + brake * (
                self.vehicle.brake_torque_nm)
            self._brake = brake
        d.ctrl[self._steer] = ackermann_angles(steer, self.vehicle)

    def step(
        self,
        speed_cmd_mps: float | None = None,
        steer: float = 0.0,
        *,
        throttle: float | None = None,
        brake: float = 0.0,
        duration_s: float = CONTROL_DT_S,
    ) -> VehicleState:
        """Advance ``duration_s`` [s] holding one command: a target speed [m/s]
        (through :attr:`speed_controller`) or a raw ``throttle`` ∈ [−1, 1] with
        ``brake`` ∈ [0, 1]; ``steer`` ∈ [−1, 1] of the maximum steering angle.
        After a run ends (``state.done_reason``) further steps change nothing.
        Raises ValueError for a non-finite command or a duration ≤ 0."""
        check_finite("Simulator.step", speed_cmd_mps=speed_cmd_mps, steer=steer,
                     throttle=throttle, brake=brake, duration_s=duration_s)
        if not duration_s > 0:
            raise ValueError(f"Simulator.step needs duration_s > 0 s, got {duration_s}")
        if self._state is None:
            raise RuntimeError("call Simulator.reset(x, y, yaw) before step()")
        if self._done is not None:
            return self._state
        if (speed_cmd_mps is None) == (throttle is None):
            raise ValueError("give exactly one of speed_cmd_mps or throttle")
        st = self._state
        if speed_cmd_mps is not None:
            throttle, brake = self.speed_controller(speed_cmd_mps, st.speed_mps, st.pitch,
                                                    duration_s)
        self._apply(throttle, brake, steer)
        velocity = vx, vy, vz = self.data.qvel[0:3].tolist()
        drag = -0.5 * AIR_DENSITY_KGPM3 * self.vehicle.drag_area_m2 * math.sqrt(
            vx * vx + vy * vy + vz * vz)
        self.data.xfrc_applied[self._chassis, 0:3] = (drag * vx, drag * vy, drag * vz)
        n = max(1, int(round(duration_s / TIMESTEP_S)))
        for done in range(0, n, GATE_STEPS):
            chunk = min(GATE_STEPS, n - done)
            self._gate_underside(chunk * TIMESTEP_S, velocity=velocity if done == 0 else None)
            mujoco.mj_step(self.model, self.data, nstep=chunk)
        if diverged(self.data.qpos, self.data.qvel, self._warnings):
            self._done = "diverged"
            self._state = replace(st, done_reason="diverged", time_s=st.time_s + n * TIMESTEP_S)
            return self._state
        self._state = self._read_state(dt=n * TIMESTEP_S)
        return self._state

    def _gate_underside(self, horizon_s: float = 0.0, force: bool = False,
                        velocity: list[float] | None = None) -> None:
        """Test belly/bumper–terrain collisions only while the terrain may reach the
        underside within ``horizon_s``: box–heightfield tests cost more than the rest
        of a step, and the underside is clear of the ground most of the time. "May
        reach" = the gap over the footprint (:func:`~dgt_lib.world.underside_gate.
        min_underside_gap`) is below UNDERSIDE_MARGIN_M plus the horizontal travel
        (terrain rising up to 1:1 under the vehicle) plus the vertical travel in
        ``horizon_s``; ``velocity``: the chassis' (3,) [m/s] if already read."""
        d = self.data
        near = force
        if not near:
            vx, vy, vz = velocity or d.qvel[0:3].tolist()
            reach = UNDERSIDE_MARGIN_M + horizon_s * (
                math.sqrt(vx * vx + vy * vy + vz * vz) + 2.0 * abs(vz))
            near = min_underside_gap(self._underside, d.xmat[self._chassis],
                                     d.xpos[self._chassis], self._z, self._x0, self._y0,
                                     self._inv_res) < reach
        aff = BIT_TERRAIN | BIT_TREE if near else BIT_TREE
        if aff != self._underside_aff:
            self.model.geom_conaffinity[self._underside_geoms] = aff
            self._underside_aff = aff

    @property
    def state(self) -> VehicleState:
        """The latest :class:`VehicleState` (after ``reset`` or ``step``)."""
        if self._state is None:
            raise RuntimeError("call Simulator.reset(x, y, yaw) first")
        return self._state

    def _read_state(self, dt: float = 0.0) -> VehicleState:
        d = self.data
        pos, vel = d.qpos[0:3].copy(), d.qvel[0:3].copy()
        w_body = d.qvel[3:6].copy()  # free joint: angular velocity in the body frame
        R = d.xmat[self._chassis].reshape(3, 3)
        (fx, _, _), (fy, _, _), (fz, r21, r22) = R.tolist()  # forward = R[:, 0], up = R[:, 2]
        yaw = math.atan2(fy, fx) % (2 * math.pi)
        pitch = math.asin(min(max(fz, -1.0), 1.0))
        roll = math.atan2(r21, r22)
        yaw_rate = float((R @ w_body)[2])
        speed = float(vel @ R[:, 0])
        wheel, chassis_terrain, tree_contact = touching(d, self._geom_kind)
        vx, vy, _ = vel.tolist()
        self._immobile_s = immobile_time(self._immobile_s, math.hypot(vx, vy), dt)
        flipped = r22 < FLIP_UP_Z
        if flipped and self._done is None:
            self._done = "flipped"
        if self._done is None:
            x, y, _ = pos.tolist()
            if not self._on_map(x, y):
                self._done = "off_map"
        return VehicleState(
            time_s=float(d.time), position=pos, yaw=yaw, roll=roll, pitch=pitch,
            velocity=vel, speed_mps=speed, yaw_rate=yaw_rate, angular_rate=w_body,
            wheel_contacts=wheel, chassis_contact=chassis_terrain, tree_contact=tree_contact,
            flipped=flipped, immobilized_s=self._immobile_s, done_reason=self._done,
        )

    def _on_map(self, x: float, y: float) -> bool:
        """Whether (x, y) [m] is on the world's grid (:meth:`GridSpec.contains` for one
        point, in scalar arithmetic; NaN is off the map)."""
        x0, y0, res, rows, cols = self._map
        col, row = (x - x0) / res, (y - y0) / res
        return 0 <= row < rows and 0 <= col < cols

    # -- rendering -------------------------------------------------------------------------

    def render_rgbd(
        self,
        camera_pose: tuple[np.ndarray, np.ndarray] | None = None,
        *,
        intrinsics: CameraIntrinsics | None = None,
        show_vehicle: bool | None = None,
    ) -> RGBDFrame:
        """Render an RGB-D frame (:class:`~dgt_lib.core.camera.RGBDFrame`).

        camera_pose: None for the onboard camera, else ``(position (3,), rotation
        (3, 3) world_from_camera)`` anywhere in the world (e.g. a survey above the
        map; see :func:`look_at`). intrinsics: image size and field of view
        (default :attr:`camera`, i.e. :data:`CAMERA`). show_vehicle: draw the vehicle
        (default: hidden from its onboard camera, shown from anywhere else).
        Depth is metric along the view axis, NaN beyond :data:`MAX_DEPTH_M`.
        """
        m, d = self.model, self.data
        cam_k = intrinsics or self.camera
        key = (cam_k.height, cam_k.width)
        if key not in self._renderers:
            self._renderers[key] = FrameRenderers.create(m, cam_k.height, cam_k.width)
        renderers = self._renderers[key]
        if camera_pose is None:
            name = "onboard"
            mujoco.mj_kinematics(m, d)
            mujoco.mj_camlight(m, d)
        else:
            name = "survey"
        cid = m.camera(name).id
        if camera_pose is not None:
            pos, rot = camera_pose
            d.cam_xpos[cid] = np.asarray(pos, np.float64)
            d.cam_xmat[cid] = np.asarray(rot, np.float64).reshape(9)
        m.cam_fovy[cid] = math.degrees(cam_k.fovy_rad)
        opt = mujoco.MjvOption()
        opt.geomgroup[VEHICLE_GEOM_GROUP] = int(
            show_vehicle if show_vehicle is not None else camera_pose is not None)
        images = []
        for r, depth in ((renderers.rgb, False), (renderers.depth, True)):
            if depth:
                r.enable_depth_rendering()
            r.update_scene(d, camera=name, scene_option=opt)
            for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                         mujoco.mjtRndFlag.mjRND_SKYBOX, mujoco.mjtRndFlag.mjRND_FOG,
                         mujoco.mjtRndFlag.mjRND_HAZE):
                r.scene.flags[flag] = 0
            images.append(r.render().copy())
            if depth:
                r.disable_depth_rendering()
        rgb, depth_m = images[0], images[1].astype(np.float32)
        depth_m[~(depth_m < MAX_DEPTH_M)] = np.nan
        return RGBDFrame(rgb=rgb, depth=depth_m, intrinsics=cam_k,
                         position=d.cam_xpos[cid].copy(),
                         rotation=d.cam_xmat[cid].reshape(3, 3).copy(), time_s=float(d.time))

    def share_renderers(self, renderers: FrameRenderers) -> None:
        """Render frames of their size with ``renderers`` instead of this simulator's own:
        simulators of tiles of one world can then share their OpenGL contexts
        (:class:`~dgt_lib.world.rendering.TerrainRenderer`)."""
        self._renderers[(renderers.rgb.height, renderers.rgb.width)] = renderers

    def close(self) -> None:
        """Free the renderers' OpenGL contexts."""
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """A camera pose ``(position (3,), rotation (3, 3) world_from_camera)`` at ``eye``
    looking at ``target`` (both (3,) [m]), image-up towards ``up``: the camera's −z
    axis points at the target (dgt_lib.core.camera convention). Looking straight down
    (``up`` parallel to the view) uses north (+y) as image-up."""
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    fwd = target - eye
    fwd /= np.linalg.norm(fwd)
    upv = np.asarray(up, np.float64)
    if abs(fwd @ upv) > 0.999:
        upv = np.array([0.0, 1.0, 0.0])
    right = np.cross(fwd, upv)
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, fwd)
    return eye, np.stack([right, cam_up, -fwd], axis=1)

