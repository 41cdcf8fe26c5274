"""The MuJoCo model of one vehicle on one world (:func:`build_model`).

The terrain is a heightfield (one vertex per world cell centre) textured with
``World.colors``, trees are collision cylinders with a visual crown, and the vehicle is
a chassis on a free joint with, per corner, a preloaded suspension slide (≈1.6 Hz,
ζ ≈ 0.5), a steering hinge (front, position servo, Ackermann split) and a sphere wheel.
Physics runs at 8 ms (implicitfast, pyramidal friction cones). The onboard camera
(:data:`CAMERA`): 160 × 120 px, vertical field of view 70°, mounted per vehicle.
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco  # dgt_lib/__init__.py has set MUJOCO_GL=egl before this import
import numpy as np

from dgt_lib.core.artifacts import data_root
from dgt_lib.core.camera import CameraIntrinsics
from dgt_lib.core.vehicle_spec import GRAVITY_MPS2, VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.world.worlds import World

# Collision bits. The vehicle's underside (wheels, belly, bumpers) touches terrain and
# trees; its upper body touches trees only (box–heightfield tests are expensive and the
# upper body only meets the ground when the vehicle has already flipped).
BIT_TERRAIN, BIT_LOW, BIT_TREE, BIT_BODY = 1, 2, 4, 8
TIMESTEP_S = 0.008  # physics step [s]: 5 per 25 Hz control period (4 ms gave the same
# premises at 0.6–0.7× the speed: benchmarks/bench_sim.py)
MAX_DEPTH_M = 40.0  # depth beyond this (and sky) is NaN [m]
WHEEL_NAMES = ("fl", "fr", "rl", "rr")
VEHICLE_GEOM_GROUP = 2  # visual group of the vehicle's geoms (hidden from its own camera)
SUSPENSION_HZ = 1.6
SUSPENSION_ZETA = 0.5
SUSPENSION_TRAVEL_M = 0.15
FRICTION = 1.0  # tyre–ground friction coefficient
CAMERA = CameraIntrinsics(width=160, height=120, fovy_rad=math.radians(70.0))  # the onboard camera


@dataclass(frozen=True)
class Lighting:
    """The scene's light: a sun (a directional light) at the zenith plus ambient light,
    no headlight, no specular, no shadows. A surface of albedo a renders as
    a·(ambient + diffuse·max(0, n·z)) whatever the camera: flat ground shows its albedo
    from the survey's nadir view and from a vehicle's onboard view alike, so a BEV cell's
    colour does not depend on who looked at it. (MuJoCo's default headlight shines along
    the view axis; with it, the onboard camera's grazing view rendered flat grass at 0.64×
    the survey's brightness, and the training world's BEV, built from both, came out
    darker than every survey-only BEV the costmaps are computed on.)"""

    ambient: float = 0.55
    diffuse: float = 0.45


LIGHTING = Lighting()
"""The light every world is rendered with (part of the frames' and BEV maps' cache keys)."""


@dataclass(frozen=True)
class Physics:
    """What a run's dynamics depend on beyond the world and the vehicle (part of the cache
    keys of everything simulated or drawn: episodes, BEV maps, ground truth, closed-loop
    trials). ``mujoco``: the release running, whose default is the one pyproject.toml pins
    — another release steps (and may draw) differently, so its artifacts are its own."""

    timestep_s: float = TIMESTEP_S
    integrator: str = "implicitfast"
    cone: str = "pyramidal"
    friction: float = FRICTION
    mujoco: str = "4.0.0"


PHYSICS = Physics(mujoco=mujoco.__version__)


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
    com_above_ground = v.com_height_m
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
    for name in WHEEL_NAMES:
        _add_wheel(spec, chassis, v, name, (k, c, preload), brake0, m_wheel, name in driven)


def _add_wheel(spec: mujoco.MjSpec, chassis, v: VehicleSpec, name: str,
               suspension: tuple[float, float, float], brake0: float, m_wheel: float,
               driven: bool) -> None:
    """One wheel ``name`` (fl, fr, rl, rr) under ``chassis``: a sprung hub (stiffness,
    damping, preload of ``suspension``), a steered knuckle at the front, the spinning
    wheel braked by ``brake0`` [N·m] of joint friction, and its motor if ``driven``."""
    k, c, preload = suspension
    r = v.wheel_radius_m
    w_max = v.max_wheel_speed_radps
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
    if driven:
        t = v.drive_torque_nm
        spec.add_actuator(name=f"motor_{name}", target=f"spin_{name}",
                          trntype=mujoco.mjtTrn.mjTRN_JOINT,
                          gaintype=mujoco.mjtGain.mjGAIN_FIXED, gainprm=[t] + [0] * 9,
                          biastype=mujoco.mjtBias.mjBIAS_AFFINE,
                          biasprm=[0, 0, -t / w_max] + [0] * 7,
                          ctrlrange=[-1.0, 1.0], ctrllimited=1,
                          forcerange=[-t, t], forcelimited=1)


MUJOCO_LOG_NAME = "MUJOCO_LOG.TXT"


def route_mujoco_log() -> Path:
    """Send MuJoCo's warning log (``MUJOCO_LOG.TXT``: a diverging simulation, "Nan, Inf or
    huge value in QACC") to the data directory, ``$DGT_DATA_DIR`` (or ``data/``), instead
    of the current directory MuJoCo writes it to by default; the warning is still printed.
    :func:`build_model` sets it in each process that builds a model (pool workers too)."""
    target = data_root() / MUJOCO_LOG_NAME
    config_type = getattr(mujoco, "MjLogConfig", None)
    if config_type is not None:  # newer MuJoCo: its own log file setting
        config = config_type.get()
        if config.logfile != str(target):
            config.logfile = str(target)
            config.set()
        return target

    def warn(message: str) -> None:  # older MuJoCo: the warning hook, written here
        print(f"WARNING: {message}", file=sys.stderr)
        with contextlib.suppress(OSError), open(target, "a", encoding="utf-8") as f:
            f.write(f"WARNING {time.ctime()}: {message}\n")

    mujoco.set_mju_user_warning(warn)
    return target


def build_model(world: World, vehicle: str | VehicleSpec) -> mujoco.MjModel:
    """Compile the MuJoCo model of ``world`` with ``vehicle`` on it (8 ms steps,
    implicitfast, pyramidal friction cones, rendering shadows/reflections off); MuJoCo's
    log goes to the data directory (:func:`route_mujoco_log`)."""
    route_mujoco_log()
    v = get_vehicle(vehicle)
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP_S
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    spec.visual.headlight.active = 0
    spec.worldbody.add_light(name="sun", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             dir=[0.0, 0.0, -1.0], pos=[0.0, 0.0, 100.0],
                             ambient=[LIGHTING.ambient] * 3, diffuse=[LIGHTING.diffuse] * 3,
                             specular=[0.0] * 3, castshadow=False)
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
