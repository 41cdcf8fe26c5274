"""MuJoCo simulation of one vehicle on one world: drive, sense, render RGB-D.

:func:`build_model` turns a :class:`~dgt_lib.worlds.World` and a
:class:`~dgt_lib.vehicles.VehicleSpec` into an ``MjModel``: the terrain as a
heightfield (one vertex per world cell centre) textured with ``World.colors``,
trees as collision cylinders with a visual crown, and the vehicle as a chassis
on a free joint with, per corner, a preloaded suspension slide (≈1.6 Hz,
ζ ≈ 0.5), a steering hinge (front, position servo, Ackermann split) and a sphere
wheel. Wheel motors follow ``τ = τ_max·(throttle − ω/ω_max)`` clamped to ±τ_max
(a torque limit and a speed cap in one); brakes are Coulomb friction on the wheel
joints (so a braked vehicle holds on a slope); drag is applied at control rate.

:class:`Simulator` wraps model and data::

    from dgt_lib.sim import Simulator
    sim = Simulator(world, "jeep")
    state = sim.reset(x, y, yaw)                 # settled on the ground, time 0
    state = sim.step(speed_cmd_mps=5.0, steer=0.2)   # 0.04 s, PID speed control
    frame = sim.render_rgbd()                    # dgt_lib.camera.RGBDFrame

Steering ``steer`` is normalised to [−1, 1] of the vehicle's maximum steering
angle (paper, Controller Integration). Physics runs at 4 ms; control at 25 Hz
(``CONTROL_DT_S``). A NaN state ends the run with ``done_reason = "diverged"``
instead of raising; other reasons: ``"flipped"``, ``"off_map"``.

Camera (:data:`CAMERA`): 160 × 120 px, vertical field of view 70°, mounted per
vehicle (``VehicleSpec.camera``: forward, up, pitched down 20°); depth is metric
along the view axis and NaN beyond ``MAX_DEPTH_M`` = 40 m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import mujoco  # dgt_lib/__init__.py has set MUJOCO_GL=egl before this import
import numpy as np

from dgt_lib.camera import CameraIntrinsics, RGBDFrame
from dgt_lib.vehicles import AIR_DENSITY_KGPM3, GRAVITY_MPS2, VehicleSpec, get_vehicle
from dgt_lib.worlds import World

TIMESTEP_S = 0.004  # physics step [s]
CONTROL_DT_S = 0.04  # control period [s] (25 Hz)
CAMERA = CameraIntrinsics(width=160, height=120, fovy_rad=math.radians(70.0))
MAX_DEPTH_M = 40.0  # depth beyond this (and sky) is NaN [m]
IMMOBILE_SPEED_MPS = 0.25  # below this horizontal speed the vehicle counts as immobile
FLIP_UP_Z = 0.3  # flipped when the chassis up-axis z-component drops below this
WHEEL_NAMES = ("fl", "fr", "rl", "rr")
# Collision bits. The vehicle's underside (wheels, belly, bumpers) touches terrain and
# trees; its upper body touches trees only (box–heightfield tests are expensive and the
# upper body only meets the ground when the vehicle has already flipped).
BIT_TERRAIN, BIT_LOW, BIT_TREE, BIT_BODY = 1, 2, 4, 8
VEHICLE_GEOM_GROUP = 2  # visual group of the vehicle's geoms (hidden from its own camera)
UNDERSIDE_MARGIN_M = 0.05  # belly/bumper collision tests run within this of the ground
GATE_STEPS = 5  # physics steps between two checks of that gap
SUSPENSION_HZ = 1.6
SUSPENSION_ZETA = 0.5
SUSPENSION_TRAVEL_M = 0.15
FRICTION = 1.0  # tyre–ground friction coefficient


_DIVERGENCE_WARNINGS = np.array([int(mujoco.mjtWarning.mjWARN_BADQPOS),
                                 int(mujoco.mjtWarning.mjWARN_BADQVEL),
                                 int(mujoco.mjtWarning.mjWARN_BADQACC)])


# Geom kinds for contact classification (world kinds sort below vehicle kinds).
_OTHER, _TERRAIN, _TREE, _CHASSIS, _WHEEL = -1, 0, 1, 2, 3


# ----------------------------------------------------------------------------- model


def _add_terrain(spec: mujoco.MjSpec, world: World) -> None:
    grid = world.grid
    h, w = grid.shape
    res = grid.resolution
    z = world.heights.astype(np.float64)
    zmin, zrange = float(z.min()), max(float(z.max() - z.min()), 0.01)
    spec.add_hfield(
        name="terrain", nrow=h, ncol=w,
        size=[(w - 1) * res / 2, (h - 1) * res / 2, zrange, 1.0],
        userdata=((z - zmin) / zrange).ravel().tolist(),
    )
    rgb = (np.clip(world.colors, 0, 1) * 255).astype(np.uint8)
    tex = spec.add_texture(name="terrain_tex", type=mujoco.mjtTexture.mjTEXTURE_2D,
                           width=w, height=h, nchannel=3)
    tex.data = np.ascontiguousarray(rgb[::-1]).tobytes()  # image row 0 = north edge
    mat = spec.add_material(name="terrain_mat", specular=0.0, shininess=0.0, reflectance=0.0)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "terrain_tex"
    x0, x1, y0, y1 = world.interior
    spec.worldbody.add_geom(
        name="terrain", type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname="terrain",
        pos=[(x0 + x1) / 2, (y0 + y1) / 2, zmin], material="terrain_mat",
        contype=BIT_TERRAIN, conaffinity=BIT_LOW, friction=[FRICTION, 0.005, 0.0001],
    )
    for i, (tx, ty, tr, th) in enumerate(np.asarray(world.trees, np.float64)):
        base = float(world.height_at(tx, ty)) - 0.5
        trunk_h = th + 0.5
        spec.worldbody.add_geom(
            name=f"tree{i}", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[tr, trunk_h / 2, 0],
            pos=[tx, ty, base + trunk_h / 2], rgba=[0.40, 0.26, 0.13, 1],
            contype=BIT_TREE, conaffinity=BIT_LOW | BIT_BODY,
        )
        crown = max(1.2, 0.3 * th)
        spec.worldbody.add_geom(
            name=f"crown{i}", type=mujoco.mjtGeom.mjGEOM_ELLIPSOID,
            size=[crown, crown, 0.6 * crown], pos=[tx, ty, base + trunk_h - 0.3 * crown],
            rgba=[0.12, 0.36, 0.12, 1], contype=0, conaffinity=0,
        )


def _add_vehicle(spec: mujoco.MjSpec, v: VehicleSpec) -> None:
    m_wheel = 0.02 * v.mass_kg  # per wheel [kg]
    m_body = v.mass_kg - 4 * m_wheel
    r = v.wheel_radius_m
    chassis = spec.worldbody.add_body(name="chassis", pos=[0, 0, 0])
    chassis.add_freejoint(name="root")
    chassis.explicitinertial = True
    chassis.mass = m_body
    # Centre of mass a quarter of the body height above the underside.
    com_above_ground = v.ground_clearance_m + 0.25 * (v.height_m - v.ground_clearance_m)
    chassis.ipos = [0, 0, com_above_ground - r]
    lx, ly, lz = v.length_m, v.width_m, v.height_m - v.ground_clearance_m
    chassis.inertia = [m_body / 12 * (ly**2 + lz**2), m_body / 12 * (lx**2 + lz**2),
                       m_body / 12 * (lx**2 + ly**2)]
    # Chassis origin: midway between the axles at wheel-centre height, so the
    # underside (belly) is ground_clearance − r above it.
    belly_z = v.ground_clearance_m - r
    low = dict(contype=BIT_LOW, conaffinity=BIT_TERRAIN | BIT_TREE,
               friction=[0.6, 0.005, 0.0001], rgba=[0.15, 0.15, 0.15, 1.0], density=0.0,
               group=VEHICLE_GEOM_GROUP)
    belly_h = 0.25
    half_w = 0.8 * v.track_m / 2
    chassis.add_geom(name="belly", type=mujoco.mjtGeom.mjGEOM_BOX,
                     size=[v.wheelbase_m / 2, half_w, belly_h / 2],
                     pos=[0, 0, belly_z + belly_h / 2], **low)
    # Bumpers under the front and rear overhangs, 0.1 m above the belly's underside:
    # they set the approach and departure angles.
    overhang = (v.length_m - v.wheelbase_m) / 2
    for sign, name in ((1, "bumper_front"), (-1, "bumper_rear")):
        chassis.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
                         size=[overhang / 2, half_w, 0.1],
                         pos=[sign * (v.wheelbase_m + overhang) / 2, 0, belly_z + 0.2], **low)
    body_bottom = belly_z + belly_h
    body_h = v.height_m - v.ground_clearance_m - belly_h
    chassis.add_geom(name="body", type=mujoco.mjtGeom.mjGEOM_BOX,
                     size=[v.length_m / 2, v.width_m / 2, body_h / 2],
                     pos=[0, 0, body_bottom + body_h / 2],
                     **{**low, "contype": BIT_BODY, "conaffinity": BIT_TREE,
                        "rgba": [*v.color, 1.0]})
    # Windows (visual only), so pictures show which way the vehicle faces.
    chassis.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 0.45 * v.width_m, 0.18 * body_h],
                     pos=[v.length_m / 2 - 0.03, 0, body_bottom + 0.75 * body_h],
                     rgba=[0.1, 0.15, 0.25, 1.0], contype=0, conaffinity=0, density=0.0,
                     group=VEHICLE_GEOM_GROUP)
    a = v.camera.pitch_down_rad
    chassis.add_camera(
        name="onboard", pos=[v.camera.forward_m, 0, v.camera.up_m],
        fovy=math.degrees(CAMERA.fovy_rad),
        xyaxes=[0, -1, 0, math.sin(a), 0, math.cos(a)],
    )
    k = (m_body / 4) * (2 * math.pi * SUSPENSION_HZ) ** 2
    c = 2 * SUSPENSION_ZETA * math.sqrt(k * m_body / 4)
    preload = (m_body / 4) * GRAVITY_MPS2 / k
    brake0 = v.rolling_resistance * v.mass_kg * GRAVITY_MPS2 * r / 4
    driven = ("fl", "fr", "rl", "rr") if v.drive == "awd" else ("rl", "rr")
    w_max = v.max_wheel_speed_radps
    for name in WHEEL_NAMES:
        x = (1 if name[0] == "f" else -1) * v.wheelbase_m / 2
        y = (1 if name[1] == "l" else -1) * v.track_m / 2
        hub = chassis.add_body(name=f"hub_{name}", pos=[x, y, 0])
        hub.add_joint(name=f"susp_{name}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1],
                      stiffness=[k, 0, 0], springref=-preload, damping=[c, 0, 0],
                      range=[-SUSPENSION_TRAVEL_M, SUSPENSION_TRAVEL_M], limited=1)
        hub.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], mass=1.0,
                     contype=0, conaffinity=0, group=3)
        parent = hub
        if name[0] == "f":
            knuckle = hub.add_body(name=f"knuckle_{name}")
            knuckle.add_joint(name=f"steer_{name}", type=mujoco.mjtJoint.mjJNT_HINGE,
                              axis=[0, 0, 1], range=[-1.0, 1.0], limited=1,
                              damping=[50.0, 0, 0], armature=1.0)
            knuckle.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], mass=1.0,
                             contype=0, conaffinity=0, group=3)
            spec.add_actuator(name=f"steer_{name}", target=f"steer_{name}",
                              trntype=mujoco.mjtTrn.mjTRN_JOINT,
                              gaintype=mujoco.mjtGain.mjGAIN_FIXED, gainprm=[20000.0] + [0] * 9,
                              biastype=mujoco.mjtBias.mjBIAS_AFFINE,
                              biasprm=[0, -20000.0, -400.0] + [0] * 7,
                              ctrlrange=[-1.0, 1.0], ctrllimited=1)
            parent = knuckle
        wheel = parent.add_body(name=f"wheel_{name}")
        # Brakes are this joint's Coulomb friction (set per step); a stiff, hard
        # friction constraint so a braked wheel holds instead of creeping.
        wheel.add_joint(name=f"spin_{name}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0],
                        frictionloss=brake0, solref_friction=[2 * TIMESTEP_S, 1.0],
                        solimp_friction=[0.999, 0.9999, 0.001, 0.5, 2.0])
        wheel.add_geom(name=f"wheel_{name}", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0],
                       mass=m_wheel, contype=BIT_LOW, conaffinity=BIT_TERRAIN | BIT_TREE,
                       friction=[FRICTION, 0.005, 0.0001], rgba=[0.1, 0.1, 0.1, 1],
                       group=VEHICLE_GEOM_GROUP)
        if name in driven:
            t = v.drive_torque_nm
            spec.add_actuator(name=f"motor_{name}", target=f"spin_{name}",
                              trntype=mujoco.mjtTrn.mjTRN_JOINT,
                              gaintype=mujoco.mjtGain.mjGAIN_FIXED, gainprm=[t] + [0] * 9,
                              biastype=mujoco.mjtBias.mjBIAS_AFFINE,
                              biasprm=[0, 0, -t / w_max] + [0] * 7,
                              ctrlrange=[-1.0, 1.0], ctrllimited=1,
                              forcerange=[-t, t], forcelimited=1)


def build_model(world: World, vehicle: str | VehicleSpec) -> mujoco.MjModel:
    """Compile the MuJoCo model of ``world`` with ``vehicle`` on it (4 ms steps,
    implicitfast, pyramidal friction cones, rendering shadows/reflections off)."""
    v = get_vehicle(vehicle)
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP_S
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    spec.visual.headlight.ambient = [0.55, 0.55, 0.55]
    spec.visual.headlight.diffuse = [0.45, 0.45, 0.45]
    spec.visual.headlight.specular = [0.0, 0.0, 0.0]
    x0, x1, y0, y1 = world.extent
    extent = max(x1 - x0, y1 - y0)
    spec.stat.extent = extent
    spec.visual.map.znear = 0.05 / extent
    spec.visual.map.zfar = 3.0 * max(MAX_DEPTH_M, extent) / extent
    spec.visual.quality.shadowsize = 0
    _add_terrain(spec, world)
    spec.worldbody.add_camera(name="survey", pos=[0, 0, 10])
    _add_vehicle(spec, v)
    return spec.compile()


# ----------------------------------------------------------------------------- control


@dataclass
class SpeedController:
    """PID speed controller with feed-forward for rolling resistance, drag and grade
    (paper, Controller Integration). Output: (throttle ∈ [−1, 1], brake ∈ [0, 1]).

    The wheel torque wanted in total is τ = r·m·a with
    a = g·(C_rr·cos φ + sin φ) + ½ρC_dA·v²/m + k_p·e + k_i·∫e + k_d·ė,
    e = v* − v, φ the pitch (uphill positive). The motors' back-EMF term is added
    back to the throttle; torque below what the motors give at zero throttle
    comes from the brakes.
    """

    vehicle: VehicleSpec
    kp: float = 1.5  # [1/s]
    ki: float = 0.6  # [1/s²]
    kd: float = 0.0  # [1]
    integral_limit: float = 4.0  # |∫e| limit [m]
    integral_band_mps: float = 1.0  # integrate only while |e| is below this [m/s]
    _integral: float = field(default=0.0, init=False)
    _last_error: float | None = field(default=None, init=False)

    def reset(self) -> None:
        """Forget the integral and derivative memory."""
        self._integral = 0.0
        self._last_error = None

    def __call__(
        self, target_mps: float, speed_mps: float, pitch_rad: float, dt_s: float
    ) -> tuple[float, float]:
        """One control update: target and measured speed along the heading [m/s],
        pitch φ [rad] (nose-up positive), period [s] → (throttle, brake)."""
        v = self.vehicle
        e = target_mps - speed_mps
        de = 0.0 if self._last_error is None else (e - self._last_error) / dt_s
        self._last_error = e
        if abs(target_mps) < 0.05 and abs(speed_mps) < 0.3:
            self._integral = 0.0
            return 0.0, 1.0  # hold still
        sign = 1.0 if target_mps >= 0 else -1.0
        resist = GRAVITY_MPS2 * v.rolling_resistance * math.cos(pitch_rad) + (
            0.5 * AIR_DENSITY_KGPM3 * v.drag_area_m2 * speed_mps**2 / v.mass_kg)
        a_ff = sign * resist + GRAVITY_MPS2 * math.sin(pitch_rad)
        integral = float(np.clip(self._integral + e * dt_s, -self.integral_limit,
                                 self.integral_limit))
        throttle, brake = self._actuate(a_ff + self.kp * e + self.ki * integral + self.kd * de,
                                        speed_mps, sign)
        saturated = (throttle >= 1.0 and e > 0) or (brake >= 1.0 and e < 0) or (
            throttle <= -1.0 and e < 0)
        if not saturated and abs(e) < self.integral_band_mps:
            # Anti-windup: integrate only near the target and while actuators have room.
            self._integral = integral
        return throttle, brake

    def _actuate(self, accel: float, speed_mps: float, sign: float) -> tuple[float, float]:
        """Wanted acceleration [m/s²] → throttle (adds the back-EMF term) or brakes."""
        v = self.vehicle
        torque = v.wheel_radius_m * v.mass_kg * accel  # total wheel torque wanted [N·m]
        n_t = v.driven_wheels * v.drive_torque_nm
        back_emf = speed_mps / v.max_speed_mps  # throttle that gives zero motor torque
        throttle = torque / n_t + back_emf
        if sign * throttle >= 0 or sign * torque >= 0:
            return float(np.clip(throttle, -1.0, 1.0)), 0.0
        # More braking than the motors give at zero throttle: friction brakes.
        brake = (abs(torque) - abs(back_emf) * n_t) / (4 * v.brake_torque_nm)
        return 0.0, float(np.clip(brake, 0.0, 1.0))


def ackermann_angles(steer: float, vehicle: VehicleSpec) -> tuple[float, float]:
    """Left and right road-wheel angles [rad] for a normalised steer ∈ [−1, 1]:
    δ = steer·δ_max on the virtual centre wheel, R = L / tan δ, and
    δ_{l,r} = atan(L / (R ∓ T/2)) (positive = left turn)."""
    d = float(np.clip(steer, -1.0, 1.0)) * vehicle.max_steer_rad
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
        kind = np.full(m.ngeom, _OTHER, np.int64)
        kind[self._terrain] = _TERRAIN
        kind[self._tree_geoms] = _TREE
        kind[self._chassis_geoms] = _CHASSIS
        kind[self._wheel_geoms] = _WHEEL + np.arange(4)
        self._geom_kind = kind
        # Underside sample points (chassis frame) for the collision gate, ≤ 0.4 m apart.
        v = self.vehicle
        half_w = 0.8 * v.track_m / 2
        xs = np.linspace(-v.length_m / 2, v.length_m / 2, int(np.ceil(v.length_m / 0.4)) + 1)
        ys = np.linspace(-half_w, half_w, int(np.ceil(2 * half_w / 0.4)) + 1)
        gx, gy = np.meshgrid(xs, ys)
        self._underside = np.stack([gx.ravel(), gy.ravel(),
                                    np.full(gx.size, v.ground_clearance_m - v.wheel_radius_m)], 1)
        self._underside_geoms = self._chassis_geoms[:3]  # belly and bumpers
        self._z = world.heights.astype(np.float64)
        if min(self._z.shape) < 2:
            raise ValueError("a world needs at least 2 × 2 height cells")
        self._inv_res = 1.0 / world.resolution
        self._x0 = world.grid.origin_xy[0] + 0.5 * world.resolution  # first cell centre
        self._y0 = world.grid.origin_xy[1] + 0.5 * world.resolution
        self._spin_dofs = np.array([m.joint(f"spin_{n}").dofadr[0] for n in WHEEL_NAMES])
        self._brake0 = m.dof_frictionloss[self._spin_dofs].copy()
        self._motors = np.array([m.actuator(f"motor_{n}").id for n in WHEEL_NAMES
                                 if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR,
                                                      f"motor_{n}") >= 0])
        self._steer = np.array([m.actuator("steer_fl").id, m.actuator("steer_fr").id])
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._immobile_s = 0.0
        self._done: str | None = None
        self._state: VehicleState | None = None

    # -- control ---------------------------------------------------------------------------

    def reset(self, x: float, y: float, yaw: float, *, settle_s: float = 1.0) -> VehicleState:
        """Place the vehicle at (x, y) [m] heading ``yaw`` [rad], drop it onto the
        terrain, let it settle ``settle_s`` with brakes on, then set time to 0."""
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
        d.ctrl[self._motors] = float(np.clip(throttle, -1.0, 1.0))
        m.dof_frictionloss[self._spin_dofs] = self._brake0 + float(np.clip(brake, 0, 1)) * (
            self.vehicle.brake_torque_nm)
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
        After a run ends (``state.done_reason``) further steps change nothing."""
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
        v = self.vehicle
        vel = self.data.qvel[0:3]
        self.data.xfrc_applied[self._chassis, 0:3] = (
            -0.5 * AIR_DENSITY_KGPM3 * v.drag_area_m2 * np.linalg.norm(vel) * vel)
        n = max(1, int(round(duration_s / TIMESTEP_S)))
        done = 0
        while done < n:
            chunk = min(GATE_STEPS, n - done)
            self._gate_underside(chunk * TIMESTEP_S)
            mujoco.mj_step(self.model, self.data, nstep=chunk)
            done += chunk
        ok = np.all(np.isfinite(self.data.qpos)) and np.all(np.isfinite(self.data.qvel))
        # MuJoCo resets the state itself when it meets NaN/huge values and counts a warning.
        if not ok or self.data.warning.number[_DIVERGENCE_WARNINGS].any():
            self._done = "diverged"
            self._state = _replace_done(st, "diverged", st.time_s + n * TIMESTEP_S)
            return self._state
        self._state = self._read_state(dt=n * TIMESTEP_S)
        return self._state

    def _gate_underside(self, horizon_s: float = 0.0, force: bool = False) -> None:
        """Test belly/bumper–terrain collisions only while the terrain may reach the
        underside within ``horizon_s``: box–heightfield tests cost more than the rest
        of a step, and the underside is clear of the ground most of the time. "May
        reach" = the gap over the footprint is below UNDERSIDE_MARGIN_M plus the
        horizontal travel (terrain rising up to 1:1 under the vehicle) plus the
        vertical travel in ``horizon_s``."""
        d = self.data
        R = d.xmat[self._chassis].reshape(3, 3)
        pts = self._underside @ R.T + d.xpos[self._chassis]
        gap = pts[:, 2] - self._terrain_z(pts[:, 0], pts[:, 1])
        reach = UNDERSIDE_MARGIN_M + horizon_s * (np.linalg.norm(d.qvel[0:3]) + 2.0 * abs(
            d.qvel[2]))
        near = force or bool(np.min(gap) < reach)
        aff = BIT_TERRAIN | BIT_TREE if near else BIT_TREE
        self.model.geom_conaffinity[self._underside_geoms] = aff

    def _terrain_z(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """World.height_at's bilinear lookup, trimmed for the per-step gate."""
        z = self._z
        h, w = z.shape
        col = np.clip((x - self._x0) * self._inv_res, 0.0, w - 1.001)
        row = np.clip((y - self._y0) * self._inv_res, 0.0, h - 1.001)
        c0, r0 = col.astype(np.intp), row.astype(np.intp)
        fc, fr = col - c0, row - r0
        top = z[r0, c0] + fc * (z[r0, c0 + 1] - z[r0, c0])
        bottom = z[r0 + 1, c0] + fc * (z[r0 + 1, c0 + 1] - z[r0 + 1, c0])
        return top + fr * (bottom - top)

    @property
    def state(self) -> VehicleState:
        """The latest :class:`VehicleState` (after ``reset`` or ``step``)."""
        if self._state is None:
            raise RuntimeError("call Simulator.reset(x, y, yaw) first")
        return self._state

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    def _read_state(self, dt: float = 0.0) -> VehicleState:
        d = self.data
        pos = d.qpos[0:3].copy()
        R = d.xmat[self._chassis].reshape(3, 3)
        fwd, up = R[:, 0], R[:, 2]
        yaw = math.atan2(fwd[1], fwd[0]) % (2 * math.pi)
        pitch = math.asin(float(np.clip(fwd[2], -1, 1)))
        roll = math.atan2(float(R[2, 1]), float(R[2, 2]))
        vel = d.qvel[0:3].copy()
        w_body = d.qvel[3:6].copy()  # free joint: angular velocity in the body frame
        yaw_rate = float((R @ w_body)[2])
        speed = float(vel @ fwd)
        wheel = np.zeros(4, bool)
        chassis_terrain = tree_contact = False
        if d.ncon:
            kind = self._geom_kind[d.contact.geom[: d.ncon]]  # (ncon, 2)
            env = kind.min(axis=1)  # _TERRAIN or _TREE when the pair touches the world
            car = kind.max(axis=1)  # _CHASSIS or a wheel (_WHEEL + index)
            tree_contact = bool(np.any(env == _TREE))
            chassis_terrain = bool(np.any((env == _TERRAIN) & (car == _CHASSIS)))
            touching = car[(env == _TERRAIN) | (env == _TREE)]
            wheel[touching[touching >= _WHEEL] - _WHEEL] = True
        if np.hypot(vel[0], vel[1]) < IMMOBILE_SPEED_MPS:
            self._immobile_s += dt
        else:
            self._immobile_s = 0.0
        flipped = bool(up[2] < FLIP_UP_Z)
        if flipped and self._done is None:
            self._done = "flipped"
        if self._done is None and not bool(self.world.grid.contains(pos[0], pos[1])):
            self._done = "off_map"
        return VehicleState(
            time_s=float(d.time), position=pos, yaw=yaw, roll=roll, pitch=pitch,
            velocity=vel, speed_mps=speed, yaw_rate=yaw_rate, angular_rate=w_body,
            wheel_contacts=wheel, chassis_contact=chassis_terrain, tree_contact=tree_contact,
            flipped=flipped, immobilized_s=self._immobile_s, done_reason=self._done,
        )

    # -- rendering -------------------------------------------------------------------------

    def render_rgbd(
        self,
        camera_pose: tuple[np.ndarray, np.ndarray] | None = None,
        *,
        intrinsics: CameraIntrinsics | None = None,
        show_vehicle: bool | None = None,
    ) -> RGBDFrame:
        """Render an RGB-D frame (:class:`~dgt_lib.camera.RGBDFrame`).

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
            self._renderers[key] = mujoco.Renderer(m, cam_k.height, cam_k.width)
        r = self._renderers[key]
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
        for depth in (False, True):
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

    def close(self) -> None:
        """Free the renderers' OpenGL contexts."""
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """A camera pose ``(position (3,), rotation (3, 3) world_from_camera)`` at ``eye``
    looking at ``target`` (both (3,) [m]), image-up towards ``up``: the camera's −z
    axis points at the target (dgt_lib.camera convention). Looking straight down
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


def _replace_done(st: VehicleState, reason: str, time_s: float) -> VehicleState:
    return replace(st, done_reason=reason, time_s=time_s)


# ----------------------------------------------------------------------------- driving helpers


@dataclass
class Trajectory:
    """A recorded run: time (N,) [s], position (N, 3) [m], yaw (N,) [rad], speed (N,)
    [m/s], pitch (N,) [rad], chassis_contact (N,) bool, and why it ended:
    ``"goal"``, ``"timeout"``, ``"immobilized"`` or a simulator ``done_reason``."""

    time_s: np.ndarray
    position: np.ndarray
    yaw: np.ndarray
    speed_mps: np.ndarray
    pitch: np.ndarray
    chassis_contact: np.ndarray
    end_reason: str

    @property
    def distance_m(self) -> np.ndarray:
        """(N,) cumulative horizontal distance travelled [m]."""
        step = np.linalg.norm(np.diff(self.position[:, :2], axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(step)])

    @property
    def progress_m(self) -> np.ndarray:
        """(N,) signed distance driven along the heading [m] (∫ speed dt): it
        decreases while the vehicle rolls backwards."""
        step = 0.5 * (self.speed_mps[1:] + self.speed_mps[:-1]) * np.diff(self.time_s)
        return np.concatenate([[0.0], np.cumsum(step)])


class PurePursuit:
    """Pure-pursuit steering along a (M, 2) waypoint path [m]: aim at the path point
    ``lookahead_m`` beyond the one nearest the rear axle and steer
    δ = atan(2L·sin α / l_d) (α: bearing of that point, l_d: its distance)."""

    def __init__(self, path_xy: np.ndarray, vehicle: VehicleSpec, lookahead_m: float = 6.0,
                 spacing_m: float = 0.25):
        path = np.asarray(path_xy, np.float64)
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        s = np.arange(0.0, cum[-1] + spacing_m, spacing_m)
        self.dense = np.stack([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])], 1)
        self.vehicle = vehicle
        self.ahead = max(1, int(round(lookahead_m / spacing_m)))
        self._i = 0

    def __call__(self, state: VehicleState) -> float:
        """Normalised steer ∈ [−1, 1] for the current state."""
        v = self.vehicle
        c, s = math.cos(state.yaw), math.sin(state.yaw)
        rear = state.position[:2] - 0.5 * v.wheelbase_m * np.array([c, s])
        # Search near the last match only, so a path that loops back is followed in order.
        lo, hi = self._i, min(len(self.dense), self._i + 8 * self.ahead)
        self._i = lo + int(np.argmin(np.linalg.norm(self.dense[lo:hi] - rear, axis=1)))
        dx, dy = self.dense[min(len(self.dense) - 1, self._i + self.ahead)] - rear
        alpha = math.atan2(dy, dx) - state.yaw
        delta = math.atan2(2 * v.wheelbase_m * math.sin(alpha), max(math.hypot(dx, dy), 1e-3))
        return float(np.clip(delta / v.max_steer_rad, -1.0, 1.0))


def follow_path(
    sim: Simulator,
    path_xy: np.ndarray,
    *,
    speed_mps: float = 5.0,
    start_yaw: float | None = None,
    max_time_s: float = 120.0,
    goal_tolerance_m: float = 3.0,
    immobilized_limit_s: float = 10.0,
    reset: bool = True,
) -> Trajectory:
    """Drive along a (M, 2) waypoint path at ``speed_mps`` with pure pursuit and the
    PID speed controller at 25 Hz, from its first point (``reset=True``, heading
    along the path unless ``start_yaw``) until within ``goal_tolerance_m`` of its
    last point, immobilized for ``immobilized_limit_s`` (paper: 10 s), a simulator
    ``done_reason``, or ``max_time_s``."""
    path = np.asarray(path_xy, np.float64)
    if reset:
        d0 = path[1] - path[0]
        yaw = math.atan2(d0[1], d0[0]) if start_yaw is None else start_yaw
        sim.reset(path[0, 0], path[0, 1], yaw)
    steer = PurePursuit(path, sim.vehicle)
    return _record(sim, lambda st: (speed_mps, steer(st)),
                   goal=path[-1], goal_tolerance_m=goal_tolerance_m, max_time_s=max_time_s,
                   immobilized_limit_s=immobilized_limit_s)


def drive_straight(sim: Simulator, x: float, y: float, yaw: float, *, speed_mps: float = 5.0,
                   steer: float = 0.0, duration_s: float = 10.0) -> Trajectory:
    """Reset at (x, y, yaw) and drive ``duration_s`` at a fixed speed command and steer."""
    sim.reset(x, y, yaw)
    return _record(sim, lambda st: (speed_mps, steer), goal=None, goal_tolerance_m=0.0,
                   max_time_s=duration_s, immobilized_limit_s=math.inf)


def _record(sim, policy, *, goal, goal_tolerance_m, max_time_s, immobilized_limit_s):
    st = sim.state
    rows = [st]
    reason = "timeout"
    while st.time_s < max_time_s - 1e-9:
        speed, steer = policy(st)
        st = sim.step(speed_cmd_mps=speed, steer=steer)
        rows.append(st)
        if st.done_reason is not None:
            reason = st.done_reason
            break
        if goal is not None and np.hypot(*(st.position[:2] - goal)) < goal_tolerance_m:
            reason = "goal"
            break
        if st.immobilized_s > immobilized_limit_s:
            reason = "immobilized"
            break
    return Trajectory(
        time_s=np.array([r.time_s for r in rows]), position=np.array([r.position for r in rows]),
        yaw=np.array([r.yaw for r in rows]), speed_mps=np.array([r.speed_mps for r in rows]),
        pitch=np.array([r.pitch for r in rows]),
        chassis_contact=np.array([r.chassis_contact for r in rows]), end_reason=reason)
