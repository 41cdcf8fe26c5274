"""Self-supervised data collection: driving episodes and the mapping survey
(paper: Methodology → Data Collection, Global Map).

Two sources of RGB-D frames feed the global BEV maps (:mod:`dgt_lib.bev`):

- **Episodes** (training world only). A vehicle spawns at a random free pose
  (:func:`spawn_pose`: not in a tree, not near the map edge, not on steep
  ground), drives forward at u = 5 m/s under the simulator's PID speed controller
  with smooth random steering — an Ornstein–Uhlenbeck process
  (:class:`OUSteering`), turned back toward the map centre near the edge and
  around tree trunks ahead (ours: random driving hits a trunk every few hundred
  metres on our maps, which would end most runs for every vehicle alike; the
  paper's jeep ran nearly full 100 s runs, ≈ 75 patches each) — and
  ends after ``episode_duration_s`` (paper: 100 s), when immobilized for
  ``immobilized_limit_s`` (below the simulator's immobile speed, 0.25 m/s;
  ours: 5 s, shorter than the 10 s of the evaluation so a stuck run wastes
  little simulation while still giving ~4 patches of the stall), or at a
  simulator end (``flipped``, ``off_map``, ``diverged``). The pose is recorded at
  the 25 Hz control rate; an onboard RGB-D frame is rendered every 5 m driven
  (about once a second at u; rendering dominates the cost, and a stalled
  vehicle would only render the same view again), on a tile of the map around
  the camera (:class:`TerrainRenderer`, several times cheaper on big maps), and
  accumulated up to 20 m depth into a per-episode
  :class:`~dgt_lib.bev.BEVAccumulator`, stored sparsely. Samples with an angular
  rate above 100°/s are simulator glitches (paper: pre-filtering): no frame is
  rendered there and the dataset cuts no patch whose label window touches one.
- **The mapping survey** (every world). The same camera (same intrinsics)
  looks straight down from ``survey_altitude_m`` above the highest terrain it
  sees, on a lattice whose footprints overlap by ``survey_overlap``
  (:func:`survey_poses`). It makes every map complete and independent of any one
  trajectory, as the paper's aggregate over all runs does, with few frames
  (smoke: 12–35 a world; 98–99.5 % of the interior observed, median |H̄ − h|
  under 1 cm; the unobserved rest lies beside tree crowns, in their occlusion
  shadow, and on the outermost cells).

The dataset built from the episodes is in :mod:`dgt_lib.dataset`
(:func:`~dgt_lib.dataset.ensure_dataset`).

Each episode is its own artifact ``data/<profile>/episodes/<vehicle>_<index>.npz``
(written atomically as it completes), so an interrupted collection resumes:
completed episodes are loaded, only the missing ones run. Episodes run through
any :class:`concurrent.futures.Executor` — a process pool of ``profile.workers``
by default, or a Dask/Ray executor passed in.

Example::

    from dgt_lib.collect import collect_episodes, ensure_bev
    episodes = collect_episodes("smoke")        # list[Episode], cached per episode
    bev = ensure_bev("hill", "smoke")           # BEVMap, data/smoke/bev/hill.npz
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; before mujoco is imported

import contextlib  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import sys  # noqa: E402
from collections import Counter  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from concurrent.futures import (  # noqa: E402
    FIRST_COMPLETED,
    Executor,
    Future,
    ProcessPoolExecutor,
    wait,
)
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from . import artifacts  # noqa: E402
from .bev import BEVAccumulator, BEVMap, bev_grid  # noqa: E402
from .camera import RGBDFrame  # noqa: E402
from .config import VEHICLES, CollectConfig, Profile, get_profile  # noqa: E402
from .geometry import GridSpec  # noqa: E402
from .pipeline import StageOutput  # noqa: E402
from .sim import CAMERA, CONTROL_DT_S, MAX_DEPTH_M, Simulator, VehicleState, look_at  # noqa: E402
from .vehicles import get_vehicle  # noqa: E402
from .worlds import WORLD_NAMES, World, from_heightmap, get_world  # noqa: E402

END_REASONS: tuple[str, ...] = ("timeout", "immobilized", "flipped", "off_map", "diverged")
"""Why an episode ended: its duration, stuck, or a simulator ``done_reason``."""

EPISODE_FIELDS: tuple[str, ...] = (
    "episode_duration_s", "speed_mps", "immobilized_limit_s", "steer_tau_s", "steer_sigma",
    "edge_margin_m", "tree_lookahead_m", "spawn_margin_m", "spawn_max_slope_deg",
    "max_angular_rate_dps", "frame_spacing_m", "frame_max_depth_m",
)
"""The :class:`CollectConfig` fields an episode depends on (its cache key)."""

EPISODE_FORMAT = 1
"""Version of the episode artifact's layout (part of its cache key)."""

SURVEY_FIELDS: tuple[str, ...] = ("survey_altitude_m", "survey_overlap")
"""The :class:`CollectConfig` fields the mapping survey depends on."""

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                "LP_NUM_THREADS")  # the last: Mesa llvmpipe's render threads


def _profile(profile: Profile | str | None) -> Profile:
    return profile if isinstance(profile, Profile) else get_profile(profile)


def _fields(config: CollectConfig, names: tuple[str, ...]) -> dict[str, object]:
    return {name: getattr(config, name) for name in names}


# ----------------------------------------------------------------------------- rendering


# Per-process caches (a model build and a GL context are paid once per worker). Each
# entry keeps its world alive, so the id(world) in its key cannot be reused.
_SIMS: dict[tuple, tuple[World, Simulator]] = {}


def simulator(world: World, vehicle: str = "jeep") -> Simulator:
    """A :class:`~dgt_lib.sim.Simulator` of ``vehicle`` on ``world``, cached per process
    (building the model and the renderer's GL context is paid once per worker)."""
    key = (id(world), get_vehicle(vehicle).name)
    if key not in _SIMS:
        _SIMS[key] = (world, Simulator(world, vehicle))
    return _SIMS[key][1]


def _tan_half_fov(intrinsics) -> tuple[float, float]:
    """tan of the half field of view across (x, image width) and along (y, height)."""
    tan_v = math.tan(0.5 * intrinsics.fovy_rad)
    return tan_v * intrinsics.width / intrinsics.height, tan_v


def survey_poses(world: World, config: CollectConfig | None = None,
                 intrinsics=None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Camera poses of the mapping survey of ``world``: nadir views on a lattice.

    The footprint of a nadir camera at distance D is 2D·tan(hfov/2) × 2D·tan(vfov/2)
    (image width along x, north up). The lattice spaces footprints computed at
    D = ``survey_altitude_m`` by (1 − ``survey_overlap``) of their size and covers
    the world's interior; each camera sits ``survey_altitude_m`` above the highest
    terrain inside its footprint, so lower ground is seen with a larger
    footprint (more overlap) and the view never starts inside a hill.
    Returns a list of ``(position (3,), rotation (3, 3) world_from_camera)``.
    """
    cfg = config or CollectConfig()
    cam = intrinsics or CAMERA
    if not 0.0 <= cfg.survey_overlap < 1.0:
        raise ValueError(f"survey_overlap must be in [0, 1), got {cfg.survey_overlap}")
    if not 0.0 < cfg.survey_altitude_m < MAX_DEPTH_M:
        raise ValueError(f"survey_altitude_m must be in (0, {MAX_DEPTH_M}) m (the camera's "
                         f"range), got {cfg.survey_altitude_m}")
    tan_x, tan_y = _tan_half_fov(cam)
    alt = cfg.survey_altitude_m
    half_x, half_y = alt * tan_x, alt * tan_y  # footprint half-sizes at D = alt [m]
    x0, x1, y0, y1 = world.interior
    nx = max(1, math.ceil((x1 - x0) / (2 * half_x * (1 - cfg.survey_overlap))))
    ny = max(1, math.ceil((y1 - y0) / (2 * half_y * (1 - cfg.survey_overlap))))
    xs = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    ys = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    grid = world.grid
    poses = []
    for y in ys:
        for x in xs:
            r0, c0 = grid.xy_to_cell(x - half_x, y - half_y)
            r1, c1 = grid.xy_to_cell(x + half_x, y + half_y)
            r0, r1 = np.clip([r0, r1], 0, grid.height - 1)
            c0, c1 = np.clip([c0, c1], 0, grid.width - 1)
            top = float(world.heights[r0 : r1 + 1, c0 : c1 + 1].max())
            eye = np.array([x, y, top + alt])
            poses.append(look_at(eye, eye - np.array([0.0, 0.0, 1.0])))
    return poses


def survey_frames(world: World, config: CollectConfig | None = None) -> Iterator[RGBDFrame]:
    """RGB-D frames of the mapping survey of ``world`` (:func:`survey_poses`), rendered
    by a headless simulator with the vehicle hidden."""
    sim = simulator(world)
    # Geom poses are only valid after a forward pass; a fresh simulator has none.
    mujoco.mj_forward(sim.model, sim.data)
    for pose in survey_poses(world, config, sim.camera):
        yield sim.render_rgbd(pose, show_vehicle=False)


TILE_STRIDE_M = 16.0
"""Spacing of the tile lattice of :class:`TerrainRenderer` [m]."""


def frame_reach_m(max_depth_m: float, intrinsics=None) -> float:
    """Farthest horizontal distance [m] from the camera of a pixel at depth ≤ ``max_depth_m``
    along the view axis: the image corner's ray, d·√(1 + tan²(hfov/2) + tan²(vfov/2))."""
    tan_x, tan_y = _tan_half_fov(intrinsics or CAMERA)
    return max_depth_m * math.sqrt(1 + tan_x**2 + tan_y**2)


class TerrainRenderer:
    """RGB-D frames of a world, rendered on a square tile of it around the camera.

    The renderer's cost follows the heightfield's triangle count — the whole map,
    whatever the camera sees (~0.3 s a frame on a 750² map, ~0.05 s on 200²).
    Frames whose points are kept only up to ``max_depth_m`` along the view axis
    are therefore rendered on a crop. Such points lie in the frustum between the
    camera and its four far corners, whose horizontal bounding box is at most
    ``frame_reach_m(max_depth_m)`` = R from the camera. Tiles are centred on a
    lattice of :data:`TILE_STRIDE_M` and reach R + stride/2 around their centre,
    so the tile nearest the box's centre contains the box; up to ``max_depth_m``
    the image equals the whole world's (same heights, colours, trees). The
    current tile is kept while it still contains the box. A world not much larger
    than a tile is rendered whole. All tiles of a world have the same size, so one
    OpenGL context serves them all: switching tiles re-uploads the heightfield and
    its texture (``mjr_uploadHField``, ``mjr_uploadTexture``; ~0.04 s) instead of
    creating a context (~0.5 s).
    """

    def __init__(self, world: World, max_depth_m: float, cache_tiles: int = 16):
        self.world = world
        self.camera = CAMERA
        self.max_depth_m = float(max_depth_m)
        res = world.grid.resolution
        half = frame_reach_m(max_depth_m, CAMERA) + 0.5 * TILE_STRIDE_M + res
        n = int(math.ceil(2 * half / res))
        h, w = world.grid.shape
        whole = n >= 0.75 * h and n >= 0.75 * w  # a tile would not save much
        self.tile_shape = (h, w) if whole else (min(n, h), min(n, w))
        self._tiles: dict[tuple[int, int], Simulator] = {}
        self._cache_tiles = cache_tiles
        self._renderer: mujoco.Renderer | None = None
        self._current: tuple[int, int] | None = None

    def restart(self) -> None:
        """Forget the current tile: from now on the tiles used depend only on the camera
        poses, so an episode renders the same frames whatever ran before it."""
        self._current = None

    def footprint(self, pose: tuple[np.ndarray, np.ndarray]) -> tuple[float, float, float, float]:
        """Horizontal bounding box (x0, x1, y0, y1) [m] of the frustum up to ``max_depth_m``."""
        pos, rot = np.asarray(pose[0], np.float64), np.asarray(pose[1], np.float64)
        tan_x, tan_y = _tan_half_fov(self.camera)
        d = self.max_depth_m
        corners = np.array([[sx * tan_x * d, sy * tan_y * d, -d]
                            for sx in (-1, 1) for sy in (-1, 1)])
        pts = np.vstack([pos, pos + corners @ rot.T])
        return pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max()

    def _tile_extent(self, key: tuple[int, int]) -> tuple[float, float, float, float]:
        g, (th, tw) = self.world.grid, self.tile_shape
        x0, y0 = g.origin_xy[0] + key[1] * g.resolution, g.origin_xy[1] + key[0] * g.resolution
        return x0, x0 + tw * g.resolution, y0, y0 + th * g.resolution

    def _covers(self, key: tuple[int, int] | None, box) -> bool:
        """Whether tile ``key`` holds all of the world inside ``box`` (x0, x1, y0, y1)."""
        if key is None:
            return False
        wx0, wx1, wy0, wy1 = self.world.grid.extent
        tx0, tx1, ty0, ty1 = self._tile_extent(key)
        return (max(box[0], wx0) >= tx0 and min(box[1], wx1) <= tx1
                and max(box[2], wy0) >= ty0 and min(box[3], wy1) <= ty1)

    def _tile_origin(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the first cell of the tile whose centre is the lattice point
        nearest (x, y), clamped into the world."""
        g = self.world.grid
        th, tw = self.tile_shape
        k = TILE_STRIDE_M / g.resolution
        r, c = g.xy_to_rc(x, y)
        r0 = int(round(round(float(r) / k) * k)) - th // 2
        c0 = int(round(round(float(c) / k) * k)) - tw // 2
        return int(np.clip(r0, 0, g.height - th)), int(np.clip(c0, 0, g.width - tw))

    def _tile(self, key: tuple[int, int]) -> Simulator:
        """The simulator of tile ``key`` (built on first use, least recently used dropped)."""
        sim = self._tiles.pop(key, None)
        if sim is None:
            world, (r0, c0), (th, tw) = self.world, key, self.tile_shape
            if (th, tw) == world.grid.shape:
                crop = world
            else:
                x0, x1, y0, y1 = self._tile_extent(key)
                trees = np.asarray(world.trees, np.float64).reshape(-1, 4)
                margin = 4.0  # more than a crown's radius [m]
                inside = ((trees[:, 0] > x0 - margin) & (trees[:, 0] < x1 + margin)
                          & (trees[:, 1] > y0 - margin) & (trees[:, 1] < y1 + margin))
                rows, cols = slice(r0, r0 + th), slice(c0, c0 + tw)
                crop = from_heightmap(world.heights[rows, cols], world.grid.resolution,
                                      origin=(x0, y0), colors=world.colors[rows, cols],
                                      trees=trees[inside], name=f"{world.name}_tile")
            sim = Simulator(crop, "jeep")
            mujoco.mj_forward(sim.model, sim.data)
            while len(self._tiles) >= self._cache_tiles:
                self._tiles.pop(next(iter(self._tiles)))
        self._tiles[key] = sim  # most recently used last
        return sim

    def render(self, pose: tuple[np.ndarray, np.ndarray]) -> RGBDFrame:
        """An RGB-D frame from camera ``pose`` = (position (3,), rotation (3, 3)
        world_from_camera), exact up to ``max_depth_m``; the vehicle is not drawn."""
        box = self.footprint(pose)
        key = self._current
        if not self._covers(key, box):
            key = self._tile_origin(0.5 * (box[0] + box[1]), 0.5 * (box[2] + box[3]))
        sim = self._tile(key)
        size = (self.camera.height, self.camera.width)
        if self._renderer is None:
            self._renderer = mujoco.Renderer(sim.model, *size)
        elif key != self._current:
            # Private members of mujoco.Renderer: it has no public way to swap models.
            r = self._renderer
            r._gl_context.make_current()
            r._model = sim.model  # the scene is built from the tile's model
            mujoco.mjr_uploadHField(sim.model, r._mjr_context, sim.model.hfield("terrain").id)
            mujoco.mjr_uploadTexture(sim.model, r._mjr_context,
                                     sim.model.texture("terrain_tex").id)
        self._current = key
        sim._renderers[size] = self._renderer  # Simulator.render_rgbd renders with it
        return sim.render_rgbd(pose, intrinsics=self.camera, show_vehicle=False)


_RENDERERS: dict[tuple, TerrainRenderer] = {}  # per process; each holds its world


def terrain_renderer(world: World, max_depth_m: float) -> TerrainRenderer:
    """A :class:`TerrainRenderer` of ``world``, cached per process."""
    key = (id(world), float(max_depth_m))
    if key not in _RENDERERS:
        _RENDERERS[key] = TerrainRenderer(world, max_depth_m)
    return _RENDERERS[key]


def onboard_camera_pose(sim: Simulator) -> tuple[np.ndarray, np.ndarray]:
    """The onboard camera's pose (position (3,), rotation (3, 3) world_from_camera)
    in the simulator's current state."""
    m, d = sim.model, sim.data
    mujoco.mj_kinematics(m, d)
    mujoco.mj_camlight(m, d)
    cid = m.camera("onboard").id
    return d.cam_xpos[cid].copy(), d.cam_xmat[cid].reshape(3, 3).copy()


# ----------------------------------------------------------------------------- episodes


@dataclass
class OUSteering:
    """Smooth random steering: an Ornstein–Uhlenbeck process on the normalised steer,

        s_{k+1} = a·s_k + σ·√(1 − a²)·ξ_k,   a = exp(−Δt/τ),   ξ_k ~ N(0, 1),

    (the exact discretisation of ds = −s/τ dt + σ√(2/τ) dW: stationary std σ,
    correlation time τ [s]), clipped to [−1, 1]. Within ``edge_margin_m`` of the
    map edge the steer blends, linearly in the distance, toward a full turn to the
    map centre (fully at half the margin) so runs explore the map instead of
    leaving it; a trunk in the corridor ahead makes the driver swerve
    (``tree_lookahead_m``).
    """

    tau_s: float
    sigma: float
    rng: np.random.Generator
    value: float = 0.0

    def __call__(self, dt_s: float) -> float:
        a = math.exp(-dt_s / self.tau_s)
        self.value = a * self.value + self.sigma * math.sqrt(1 - a * a) * self.rng.standard_normal()
        return float(np.clip(self.value, -1.0, 1.0))


def _homing(steer: float, x: float, y: float, yaw: float, grid: GridSpec, margin_m: float
            ) -> float:
    """Blend ``steer`` toward the map centre near the edge (see :class:`OUSteering`)."""
    x0, x1, y0, y1 = grid.extent
    d_edge = min(x - x0, x1 - x, y - y0, y1 - y)
    w = float(np.clip(2.0 * (margin_m - d_edge) / margin_m, 0.0, 1.0)) if margin_m > 0 else 0.0
    if w == 0.0:
        return steer
    to_centre = math.atan2(0.5 * (y0 + y1) - y, 0.5 * (x0 + x1) - x)
    err = (to_centre - yaw + math.pi) % (2 * math.pi) - math.pi
    home = float(np.clip(2.0 * err, -1.0, 1.0))
    return (1 - w) * steer + w * home


def _avoid_trees(steer: float, x: float, y: float, yaw: float, trees: np.ndarray,
                 half_width_m: float, lookahead_m: float) -> float:
    """Steer fully away from the nearest trunk in the corridor ahead, else ``steer``.

    trees: (N, 4) x, y, radius, height. A trunk is in the corridor when it lies
    0–``lookahead_m`` ahead and its edge comes within ``half_width_m`` + 1 m of
    the vehicle's centre line; the vehicle turns away from its side."""
    if lookahead_m <= 0 or len(trees) == 0:
        return steer
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = trees[:, 0] - x, trees[:, 1] - y
    ahead, left = dx * c + dy * s, -dx * s + dy * c
    threat = (ahead > 0) & (ahead < lookahead_m) & (np.abs(left) < half_width_m + 1.0
                                                     + trees[:, 2])
    if not threat.any():
        return steer
    i = np.flatnonzero(threat)[np.argmin(ahead[threat])]
    return -1.0 if left[i] >= 0 else 1.0


def spawn_pose(world: World, vehicle: str, rng: np.random.Generator,
               config: CollectConfig | None = None, max_tries: int = 10_000) -> np.ndarray:
    """A random free start pose (x [m], y [m], yaw [rad]) on ``world``.

    Free: at least ``spawn_margin_m`` from the map edge, the vehicle's
    half-length plus 1 m clear of every trunk, and the steepest slope within the
    vehicle's half-length at most ``spawn_max_slope_deg``. Raises RuntimeError if
    no such pose is found in ``max_tries`` draws.
    """
    cfg = config or CollectConfig()
    spec = get_vehicle(vehicle)
    x0, x1, y0, y1 = world.grid.extent
    m = cfg.spawn_margin_m
    if x1 - x0 <= 2 * m or y1 - y0 <= 2 * m:
        raise ValueError(f"world {world.name!r} is too small for a spawn margin of {m} m")
    slope = world.slope_deg()
    reach = 0.5 * spec.length_m
    trees = np.asarray(world.trees, np.float64).reshape(-1, 4)
    offsets = reach * np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1],
                                [0.7, 0.7], [-0.7, 0.7], [0.7, -0.7], [-0.7, -0.7]])
    for _ in range(max_tries):
        x, y = rng.uniform(x0 + m, x1 - m), rng.uniform(y0 + m, y1 - m)
        if len(trees) and np.any(np.hypot(trees[:, 0] - x, trees[:, 1] - y)
                                 < trees[:, 2] + reach + 1.0):
            continue
        r, c = world.grid.xy_to_cell(x + offsets[:, 0], y + offsets[:, 1])
        r = np.clip(r, 0, world.grid.height - 1)
        c = np.clip(c, 0, world.grid.width - 1)
        if slope[r, c].max() > cfg.spawn_max_slope_deg:
            continue
        return np.array([x, y, rng.uniform(0.0, 2 * np.pi)])
    raise RuntimeError(f"no free spawn pose for {spec.name} on {world.name!r} "
                       f"in {max_tries} tries")


@dataclass
class Episode:
    """One recorded run of one vehicle on the training world.

    time_s: (T,) [s] from 0 at the 25 Hz control rate. pose: (T, 3) x [m], y [m],
    yaw [rad]. z: (T,) chassis height [m]. speed_mps: (T,) signed speed along the
    heading. angular_rate_dps: (T,) body angular-rate magnitude [°/s].
    valid: (T,) bool, False where the angular rate exceeds the glitch threshold.
    end_reason: one of :data:`END_REASONS`. n_frames: onboard frames rendered.
    bev: the frames' accumulated BEV statistics in sparse form (``None`` when
    loaded without it), see :meth:`BEVAccumulator.to_sparse`.
    """

    vehicle: str
    index: int
    seed: int
    time_s: np.ndarray
    pose: np.ndarray
    z: np.ndarray
    speed_mps: np.ndarray
    angular_rate_dps: np.ndarray
    valid: np.ndarray
    end_reason: str
    n_frames: int
    bev: dict[str, np.ndarray] | None = None

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0]) if len(self.time_s) else 0.0

    def to_arrays(self) -> dict[str, np.ndarray]:
        """A dict of arrays for an ``.npz`` artifact (no pickled objects)."""
        out = {
            "vehicle": np.array(self.vehicle), "index": np.array(self.index),
            "seed": np.array(self.seed), "time_s": self.time_s, "pose": self.pose,
            "z": self.z, "speed_mps": self.speed_mps,
            "angular_rate_dps": self.angular_rate_dps, "valid": self.valid,
            "end_reason": np.array(self.end_reason), "n_frames": np.array(self.n_frames),
        }
        for k, v in (self.bev or {}).items():
            out[f"bev_{k}"] = v
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], with_bev: bool = True) -> Episode:
        bev = {k[4:]: v for k, v in arrays.items() if k.startswith("bev_")}
        return cls(
            vehicle=str(arrays["vehicle"]), index=int(arrays["index"]),
            seed=int(arrays["seed"]), time_s=arrays["time_s"], pose=arrays["pose"],
            z=arrays["z"], speed_mps=arrays["speed_mps"],
            angular_rate_dps=arrays["angular_rate_dps"], valid=arrays["valid"],
            end_reason=str(arrays["end_reason"]), n_frames=int(arrays["n_frames"]),
            bev=bev if with_bev and bev else None,
        )


def episode_seed(profile_seed: int, vehicle: str, index: int) -> int:
    """The seed of episode ``index`` of ``vehicle``: independent streams per vehicle,
    so changing one vehicle's episode count changes no other episode."""
    ss = np.random.SeedSequence([int(profile_seed), VEHICLES.index(get_vehicle(vehicle).name),
                                 int(index)])
    return int(ss.generate_state(1)[0])


def run_episode(
    world: World,
    vehicle: str,
    seed: int,
    config: CollectConfig | None = None,
    *,
    start_pose: np.ndarray | None = None,
    steer: Callable[[VehicleState], float] | None = None,
    index: int = 0,
    render: bool = True,
) -> Episode:
    """Drive one episode and record it (see the module docstring).

    world: usually the training world. seed: spawn pose and steering noise.
    start_pose: (3,) x, y, yaw to use instead of a random :func:`spawn_pose`.
    steer: optional policy ``state -> steer ∈ [−1, 1]`` replacing the OU steering.
    render: render an onboard frame every ``frame_spacing_m`` driven (and at the start)
    into the episode's BEV; a stalled vehicle renders nothing new.
    Deterministic in ``seed`` (the simulator is bitwise repeatable).
    """
    cfg = config or CollectConfig()
    spec = get_vehicle(vehicle)
    rng = np.random.default_rng(seed)
    pose0 = spawn_pose(world, spec.name, rng, cfg) if start_pose is None else np.asarray(
        start_pose, np.float64)
    ou = OUSteering(cfg.steer_tau_s, cfg.steer_sigma, rng)
    trees = np.asarray(world.trees, np.float64).reshape(-1, 4)
    sim = simulator(world, spec.name)
    grid = bev_grid(world.grid.extent)
    acc = BEVAccumulator(grid) if render else None
    renderer = terrain_renderer(world, cfg.frame_max_depth_m) if render else None
    if renderer is not None:
        renderer.restart()
    st = sim.reset(float(pose0[0]), float(pose0[1]), float(pose0[2]))
    n_max = int(round(cfg.episode_duration_s / CONTROL_DT_S)) + 1
    rows = np.empty((n_max, 7))  # t, x, y, yaw, z, speed, |ω| [°/s]
    n, n_frames, reason = 0, 0, "timeout"
    travelled, next_frame_m, last_xy = 0.0, 0.0, st.position[:2].copy()
    while True:
        rate = math.degrees(float(np.linalg.norm(st.angular_rate)))
        rows[n] = (st.time_s, st.position[0], st.position[1], st.yaw, st.position[2],
                   st.speed_mps, rate)
        n += 1
        travelled += float(np.hypot(*(st.position[:2] - last_xy)))
        last_xy = st.position[:2].copy()
        if render and travelled >= next_frame_m and rate <= cfg.max_angular_rate_dps:
            frame = renderer.render(onboard_camera_pose(sim))
            acc.add_frame(frame, max_depth_m=cfg.frame_max_depth_m)
            n_frames += 1  # (no frames during glitches)
            next_frame_m = travelled + cfg.frame_spacing_m
        if st.done_reason is not None:
            reason = st.done_reason
            break
        if st.immobilized_s > cfg.immobilized_limit_s:
            reason = "immobilized"
            break
        if n >= n_max or st.time_s >= cfg.episode_duration_s - 1e-9:
            break
        if steer is not None:
            s = steer(st)
        else:
            x, y = st.position[0], st.position[1]
            s = _homing(ou(CONTROL_DT_S), x, y, st.yaw, world.grid, cfg.edge_margin_m)
            s = _avoid_trees(s, x, y, st.yaw, trees, 0.5 * spec.width_m, cfg.tree_lookahead_m)
        st = sim.step(speed_cmd_mps=cfg.speed_mps, steer=s)
    rows = rows[:n]
    if reason == "diverged":  # the simulator repeats the last good state: drop it
        rows = rows[:-1] if n > 1 else rows
    keep = np.concatenate([[True], np.diff(rows[:, 0]) > 0])  # strictly increasing time
    rows = rows[keep]
    return Episode(
        vehicle=spec.name, index=int(index), seed=int(seed),
        time_s=rows[:, 0].astype(np.float32), pose=rows[:, 1:4].astype(np.float32),
        z=rows[:, 4].astype(np.float32), speed_mps=rows[:, 5].astype(np.float32),
        angular_rate_dps=rows[:, 6].astype(np.float32),
        valid=rows[:, 6] <= cfg.max_angular_rate_dps, end_reason=reason,
        n_frames=n_frames, bev=acc.to_sparse() if render else None,
    )


def episode_relpath(vehicle: str, index: int) -> str:
    """``episodes/<vehicle>_<index>.npz`` under ``data/<profile>/``."""
    return f"episodes/{vehicle}_{index:04d}.npz"


def episode_config(profile: Profile, vehicle: str, index: int) -> dict[str, object]:
    """What one episode depends on (its artifact's cache key)."""
    return {"format": EPISODE_FORMAT, "episode": _fields(profile.collect, EPISODE_FIELDS),
            "worlds": profile.worlds, "seed": profile.seed, "vehicle": get_vehicle(vehicle),
            "index": int(index), "camera": CAMERA}


def limit_threads() -> None:
    """One BLAS/OpenMP/torch/llvmpipe thread per worker; headless EGL rendering."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    for var in _THREAD_VARS:
        os.environ[var] = "1"
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


def _episode_job(profile: Profile, vehicle: str, index: int, in_worker: bool = True
                 ) -> dict[str, np.ndarray]:
    """Worker entry point: run one episode of the training world, return its arrays."""
    if in_worker:  # a Dask/Ray worker has no initializer of ours; this process keeps its own
        limit_threads()
    world = get_world("training", profile)
    ep = run_episode(world, vehicle, episode_seed(profile.seed, vehicle, index),
                     profile.collect, index=index)
    return ep.to_arrays()


class SerialExecutor(Executor):
    """An :class:`~concurrent.futures.Executor` that runs each job in this process
    when it is submitted (``profile.workers <= 1``, debugging, tests)."""

    def submit(self, fn, /, *args, **kwargs) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - delivered through the future
            future.set_exception(exc)
        return future


@contextlib.contextmanager
def _worker_environment():
    """Environment inherited by spawned workers: EGL and single-threaded BLAS."""
    saved = {k: os.environ.get(k) for k in ("MUJOCO_GL", *_THREAD_VARS)}
    os.environ.setdefault("MUJOCO_GL", "egl")
    for var in _THREAD_VARS:
        os.environ[var] = "1"
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def default_executor(workers: int) -> Executor:
    """A process pool of ``workers`` spawned processes (each one thread, EGL), or a
    :class:`SerialExecutor` for ``workers <= 1``."""
    if workers <= 1:
        return SerialExecutor()
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(
        "spawn"), initializer=limit_threads)


def load_episode(path: Path, with_bev: bool = False) -> Episode:
    """Read an episode artifact (the trajectory; its sparse BEV sums if ``with_bev``)."""
    return Episode.from_arrays(artifacts.load(path), with_bev=with_bev)


def collect_episodes(
    profile: Profile | str | None = None,
    *,
    executor: Executor | None = None,
    progress: bool = True,
    on_episode: Callable[[Episode], None] | None = None,
    max_in_flight: int | None = None,
) -> list[Episode]:
    """All episodes of ``profile`` (``profile.collect.episodes`` per vehicle), each
    loaded from its artifact when it is there and built otherwise.

    executor: any :class:`concurrent.futures.Executor` (a Dask or Ray one for a
    cluster); default :func:`default_executor` with ``profile.workers``, shut down
    afterwards. Missing episodes are submitted at most ``max_in_flight`` at a time
    (default 2 per worker; 1 for a :class:`SerialExecutor`) and each is written as
    soon as it completes, so an interruption loses only the episodes in flight.
    on_episode: called in this
    process with every newly computed episode (after it is saved).
    Returns the episodes in :data:`VEHICLES` order, by index, *without* their
    sparse BEV sums (see :func:`load_episode`) to keep memory small.
    """
    prof = _profile(profile)
    jobs = [(v, i) for v, n in zip(VEHICLES, prof.collect.episodes, strict=True)
            for i in range(n)]
    root = artifacts.profile_dir(prof.name)
    done: dict[tuple[str, int], Episode] = {}
    todo = []
    for v, i in jobs:
        rel = episode_relpath(v, i)
        if artifacts.is_fresh(rel, episode_config(prof, v, i), profile=prof.name):
            try:
                done[(v, i)] = load_episode(root / rel)
                continue
            except Exception:  # noqa: BLE001 - unreadable: recompute it
                pass
        todo.append((v, i))
    if todo:
        own = executor is None
        ex = default_executor(prof.workers) if own else executor
        serial = isinstance(ex, SerialExecutor)  # runs at submit: one at a time
        limit = max_in_flight or (1 if serial else max(2, 2 * prof.workers))
        order = {job: k for k, job in enumerate(todo)}
        pending: dict[Future, tuple[str, int]] = {}
        queue = iter(todo)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(todo), desc=f"episodes ({prof.name})", unit="ep")
        try:
            with _worker_environment():
                def fill() -> None:
                    while len(pending) < limit:
                        job = next(queue, None)
                        if job is None:
                            return
                        pending[ex.submit(_episode_job, prof, *job, not serial)] = job

                fill()
                while pending:
                    finished, _ = wait(list(pending), return_when=FIRST_COMPLETED)
                    for fut in sorted(finished, key=lambda f: order[pending[f]]):
                        v, i = pending.pop(fut)
                        arrays = fut.result()
                        artifacts.ensure(episode_relpath(v, i), episode_config(prof, v, i),
                                         lambda arrays=arrays: arrays, profile=prof.name)
                        ep = Episode.from_arrays(arrays, with_bev=False)
                        done[(v, i)] = ep
                        if bar is not None:
                            bar.update(1)
                        if on_episode is not None:
                            on_episode(ep)
                    fill()
        finally:
            if bar is not None:
                bar.close()
            if own:
                ex.shutdown(wait=True, cancel_futures=True)
    return [done[job] for job in jobs]


def episode_summary(episodes: list[Episode]) -> str:
    """One line: episodes per vehicle with their end reasons and mean duration."""
    parts = []
    for v in VEHICLES:
        eps = [e for e in episodes if e.vehicle == v]
        if not eps:
            continue
        reasons = Counter(e.end_reason for e in eps)
        why = ", ".join(f"{r} {reasons[r]}" for r in END_REASONS if reasons[r])
        mean_s = np.mean([e.duration_s for e in eps])
        parts.append(f"{v} {len(eps)} ({why}; mean {mean_s:.0f} s)")
    return "; ".join(parts)


# ----------------------------------------------------------------------------- BEV maps


def bev_config(world_name: str, profile: Profile) -> dict[str, object]:
    """What the BEV of ``world_name`` depends on: the world, the survey and, for the
    training world, the episodes."""
    cfg: dict[str, object] = {"world": world_name, "worlds": profile.worlds,
                              "seed": profile.seed, "camera": CAMERA,
                              "survey": _fields(profile.collect, SURVEY_FIELDS)}
    if world_name == "training":  # one digest, not 1,300 configurations in the metadata
        cfg["episodes"] = artifacts.config_hash(
            [episode_config(profile, v, i)
             for v, n in zip(VEHICLES, profile.collect.episodes, strict=True) for i in range(n)])
    return cfg


def build_bev(world: World, config: CollectConfig | None = None,
              episode_paths: list[Path] = (), progress: bool = False
              ) -> tuple[BEVMap, int, int]:
    """The BEV map of ``world`` from its survey plus the stored frames of episodes.

    Returns the map, the number of survey frames and of episode frames."""
    acc = BEVAccumulator(bev_grid(world.grid.extent))
    frames = survey_frames(world, config)
    if progress:
        from tqdm.auto import tqdm

        frames = tqdm(frames, total=len(survey_poses(world, config)),
                      desc=f"survey {world.name}", unit="frame")
    n_survey = 0
    for frame in frames:
        acc.add_frame(frame)
        n_survey += 1
    n_episode = 0
    for path in episode_paths:
        ep = load_episode(path, with_bev=True)
        if ep.bev is not None:
            acc.add_sparse(ep.bev)
        n_episode += ep.n_frames
    return acc.result(), n_survey, n_episode


def ensure_bev(world_name: str, profile: Profile | str | None = None, *,
               executor: Executor | None = None, progress: bool = True) -> BEVMap:
    """The global BEV map of a world, cached as ``data/<profile>/bev/<world>.npz``.

    Every world is mapped by the survey; the training world's map also
    aggregates the onboard frames of all episodes (collected first if needed,
    through ``executor``).
    """
    return BEVMap.from_arrays(_ensure_bev_arrays(world_name, profile, executor, progress))


def _ensure_bev_arrays(world_name: str, profile: Profile | str | None,
                       executor: Executor | None, progress: bool) -> dict[str, np.ndarray]:
    """The BEV artifact's arrays (the map plus ``survey_frames``, ``episode_frames``)."""
    if world_name not in WORLD_NAMES:
        raise ValueError(f"unknown world {world_name!r}; valid worlds: {', '.join(WORLD_NAMES)}")
    prof = _profile(profile)
    world = get_world(world_name, prof)

    def build() -> dict[str, np.ndarray]:
        paths: list[Path] = []
        if world_name == "training":
            collect_episodes(prof, executor=executor, progress=progress)
            root = artifacts.profile_dir(prof.name)
            paths = [root / episode_relpath(v, i)
                     for v, n in zip(VEHICLES, prof.collect.episodes, strict=True)
                     for i in range(n)]
        bev, n_survey, n_episode = build_bev(world, prof.collect, paths, progress=progress)
        return {**bev.to_arrays(), "survey_frames": np.array(n_survey),
                "episode_frames": np.array(n_episode)}

    return artifacts.ensure(bev_relpath(world_name), bev_config(world_name, prof), build,
                            profile=prof.name)


def bev_relpath(world_name: str) -> str:
    """``bev/<world>.npz`` under ``data/<profile>/``."""
    return f"bev/{world_name}.npz"


def bev_quality(bev: BEVMap, world: World) -> dict[str, float]:
    """How well a BEV map matches the true terrain.

    coverage: fraction of the cells centred in the world's interior that are
    observed. height_median_abs_err_m: median |H̄ − h| [m] over observed interior
    cells, h the true terrain height at the cell centre (tree cells included)."""
    x, y = bev.grid.cell_centers()
    x0, x1, y0, y1 = world.interior
    inside = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    seen = inside & bev.observed
    err = np.abs(bev.mean_height[seen] - world.height_at(x[seen], y[seen]))
    return {"coverage": float(seen.sum() / max(inside.sum(), 1)),
            "height_median_abs_err_m": float(np.median(err)) if err.size else math.inf}


# ----------------------------------------------------------------------------- stages


def stage_collect(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: all collection episodes (cached per episode)."""
    episodes = collect_episodes(profile)
    root = artifacts.profile_dir(_profile(profile).name) / "episodes"
    return StageOutput([root], f"{len(episodes)} episodes: {episode_summary(episodes)}")


def stage_bev(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: BEV maps of the training, hill, ridge and eval worlds."""
    prof = _profile(profile)
    paths, parts = [], []
    for name in WORLD_NAMES:
        meta = _ensure_bev_arrays(name, prof, None, True)
        q = bev_quality(BEVMap.from_arrays(meta), get_world(name, prof))
        paths.append(artifacts.profile_dir(prof.name) / bev_relpath(name))
        parts.append(f"{name} {q['coverage']:.1%} observed, |H̄−h| median "
                     f"{q['height_median_abs_err_m'] * 100:.1f} cm "
                     f"({int(meta['survey_frames'])}+{int(meta['episode_frames'])} frames)")
    return StageOutput(paths, "; ".join(parts))
