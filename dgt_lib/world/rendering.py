"""RGB-D rendering of a world: the mapping survey's nadir views, onboard frames on a
tile of the map around the camera, and the onboard camera's pose (paper: Global Map).

The survey (:func:`survey_poses`, :func:`survey_frames`): the onboard camera's
intrinsics, looking straight down from ``survey_altitude_m`` above the highest terrain it
sees, on a lattice whose footprints overlap by ``survey_overlap`` (smoke: 12–35 frames a
world; 98–99.5 % of the interior observed, median |H̄ − h| under 1 cm; the unobserved
rest lies beside tree crowns, in their occlusion shadow, and on the outermost cells).
"""

from __future__ import annotations

import math  # noqa: E402
from collections.abc import Iterator  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from dgt_lib.core.camera import RGBDFrame
from dgt_lib.core.config import CollectConfig
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.world.mujoco_model import CAMERA, MAX_DEPTH_M
from dgt_lib.world.simulator import FrameRenderers, Simulator, look_at
from dgt_lib.world.worlds import World, from_heightmap

# Per-process caches (a model build and a GL context are paid once per worker). Each
# entry keeps its world alive, so the id(world) in its key cannot be reused.
_SIMS: dict[tuple, tuple[World, Simulator]] = {}


def simulator(world: World, vehicle: str | VehicleSpec = "jeep") -> Simulator:
    """A :class:`~dgt_lib.world.simulator.Simulator` of ``vehicle`` (a name or any spec) on
    ``world``, cached per process by the spec itself (two generated vehicles may share a
    name) — building the model and the renderer's GL context is paid once per worker."""
    key = (id(world), get_vehicle(vehicle))
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
        self._renderers: FrameRenderers | None = None
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
        if self._renderers is None:
            self._renderers = FrameRenderers.create(sim.model, *size)
        elif key != self._current:
            # Private members of mujoco.Renderer: it has no public way to swap models.
            for r in self._renderers.distinct():
                r._gl_context.make_current()
                r._model = sim.model  # the scene is built from the tile's model
                mujoco.mjr_uploadHField(sim.model, r._mjr_context,
                                        sim.model.hfield("terrain").id)
            r = self._renderers.rgb
            r._gl_context.make_current()  # the depth pass draws no texture
            mujoco.mjr_uploadTexture(sim.model, r._mjr_context,
                                     sim.model.texture("terrain_tex").id)
        self._current = key
        sim.share_renderers(self._renderers)  # Simulator.render_rgbd renders with them
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
