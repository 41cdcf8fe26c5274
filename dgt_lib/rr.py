"""rerun logging: the one module that owns entity paths and blueprints.

Library stages never import rerun; notebooks and experiment runners hand their
arrays to a :class:`Recording`, which writes a ``.rrd`` file that opens in the
viewer (``rerun data/<profile>/runs/NAME.rrd``) on a useful layout.

Entity tree (world frame: x east, y north, z up, metres)::

    world/terrain                 terrain mesh coloured like the BEV RGB
    world/frames/<name>           camera poses of RGB-D frames (Pinhole + image)
    world/paths/<method>          planned paths, drawn on the terrain
    world/vehicle/<name>          executed trajectory and current pose
    maps/bev/{rgb,height,std,gradient,observed}
    maps/costmap/<vehicle>/<method>/heading_<k>   one image per heading layer
    maps/occupancy
    plots/<name>/<series>         scalars over time (speed, locomotion …)

Timelines: ``sim_time`` (seconds of simulated time) and ``step`` (sequence).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from dgt_lib.core.geometry import GridSpec
from dgt_lib.evaluation.experiments import ExperimentResult
from dgt_lib.evaluation.paper import PAPER
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.world.worlds import World

TERRAIN = "world/terrain"
FRAMES = "world/frames"
PATHS = "world/paths"
VEHICLES = "world/vehicle"
BEV = "maps/bev"
COSTMAPS = "maps/costmap"
OCCUPANCY = "maps/occupancy"
PLOTS = "plots"

BEV_NAMES = ("rgb", "height", "std", "gradient")


def _map_image(array: np.ndarray) -> np.ndarray:
    """A grid array (rows grow with y) as an image (row 0 at the top = north up)."""
    return np.ascontiguousarray(np.flip(array, axis=0))


def _rgba(color) -> list[int]:
    c = np.asarray(color, dtype=np.float64)
    if c.max() <= 1.0:
        c = c * 255.0
    c = np.clip(np.rint(c), 0, 255).astype(int).tolist()
    return c + [255] * (4 - len(c))


def default_blueprint(extra_views: list | None = None) -> rrb.Blueprint:
    """3D world on the left; maps and plots tabbed on the right."""
    right = [
        rrb.Spatial2DView(origin=BEV, name="BEV map"),
        rrb.Spatial2DView(origin=COSTMAPS, name="costmaps"),
        rrb.TimeSeriesView(origin=PLOTS, name="plots"),
    ]
    right += extra_views or []
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="world"),
            rrb.Tabs(*right),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


class Recording:
    """A rerun recording written to a ``.rrd`` file. Use as a context manager::

        with Recording(path, "experiment1") as rec:
            rec.log_terrain(heights, colors, grid)
            rec.log_path("dgt", path_xyz)

    The file is complete (flushed) when the ``with`` block ends.
    """

    def __init__(self, path: str | Path, name: str = "dgt-kit",
                 blueprint: rrb.Blueprint | None = None):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.stream = rr.RecordingStream("dgt-kit", recording_id=name)
        self.stream.save(str(self.path), default_blueprint=blueprint or default_blueprint())

    # -- life cycle -------------------------------------------------------
    def close(self) -> Path:
        """Flush and close the file; returns its path."""
        self.stream.flush()
        self.stream.disconnect()
        return self.path

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def set_time(self, seconds: float | None = None, step: int | None = None) -> None:
        """Set the current time on the ``sim_time`` and/or ``step`` timelines."""
        if seconds is not None:
            self.stream.set_time("sim_time", duration=float(seconds))
        if step is not None:
            self.stream.set_time("step", sequence=int(step))

    # -- static maps ------------------------------------------------------
    def log_terrain(self, heights: np.ndarray, colors: np.ndarray | None, grid: GridSpec,
                    *, max_cells: int = 200_000) -> None:
        """A coloured triangle mesh of a height grid (H, W) [m]; colours (H, W, 3) in 0..1.

        Grids larger than ``max_cells`` are subsampled for the viewer.
        """
        step = max(1, int(np.ceil(np.sqrt(heights.size / max_cells))))
        h = np.asarray(heights, dtype=np.float32)[::step, ::step]
        rows, cols = np.mgrid[0 : grid.height : step, 0 : grid.width : step]
        x, y = grid.cell_to_xy(rows, cols)
        verts = np.stack([x.ravel(), y.ravel(), h.ravel()], axis=1).astype(np.float32)
        hh, ww = h.shape
        idx = np.arange(hh * ww).reshape(hh, ww)
        a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
        tris = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                               np.stack([a, d, c], -1).reshape(-1, 3)]).astype(np.uint32)
        if colors is None:
            span = max(float(np.ptp(h)), 1e-6)
            g = (h - h.min()) / span
            cols = np.stack([0.3 + 0.5 * g, 0.5 + 0.3 * g, 0.3 + 0.2 * g], -1)
        else:
            cols = np.asarray(colors, dtype=np.float32)[::step, ::step]
            if cols.max() > 1.0:
                cols = cols / 255.0
        vcols = (np.clip(cols.reshape(-1, 3), 0, 1) * 255).astype(np.uint8)
        self.stream.log(TERRAIN, rr.Mesh3D(vertex_positions=verts, triangle_indices=tris,
                                           vertex_colors=vcols), static=True)

    def log_bev(self, channels: np.ndarray, observed: np.ndarray) -> None:
        """The six BEV channels (6, H, W) (R, G, B, H̄, σ_H, ‖∇H̄‖) and the observed mask."""
        rgb = np.clip(np.moveaxis(channels[:3], 0, -1), 0, 1)
        self.stream.log(f"{BEV}/rgb", rr.Image(_map_image((rgb * 255).astype(np.uint8))),
                        static=True)
        for name, layer in zip(BEV_NAMES[1:], channels[3:6], strict=True):
            self.stream.log(f"{BEV}/{name}", rr.Tensor(_map_image(layer.astype(np.float32))),
                            static=True)
        self.stream.log(f"{BEV}/observed",
                        rr.SegmentationImage(_map_image(observed.astype(np.uint8))), static=True)

    def log_costmap(self, costmap: np.ndarray, vehicle: str, method: str = "dgt") -> None:
        """A directional costmap (K, H, W) in [0, 1]; one image per heading θ_k = 2πk/K."""
        base = f"{COSTMAPS}/{vehicle}/{method}"
        self.stream.log(base, rr.Tensor(np.stack([_map_image(c) for c in costmap]),
                                        dim_names=["heading", "north", "east"]), static=True)
        for k, layer in enumerate(costmap):
            img = (np.clip(_map_image(layer), 0, 1) * 255).astype(np.uint8)
            self.stream.log(f"{base}/heading_{k}", rr.Image(img), static=True)

    def log_occupancy(self, occupancy: np.ndarray) -> None:
        """Occupancy (H, W): 0 free, 1 occupied, 2 unobserved."""
        self.stream.log(OCCUPANCY, rr.SegmentationImage(_map_image(occupancy.astype(np.uint8))),
                        static=True)

    # -- paths and trajectories -------------------------------------------
    def log_path(self, name: str, xyz: np.ndarray, color=(0.1, 0.3, 1.0),
                 radius_m: float = 0.3) -> None:
        """A planned path (N, 3) world points [m] (z already on the terrain, plus clearance)."""
        self.stream.log(f"{PATHS}/{name}",
                        rr.LineStrips3D([np.asarray(xyz, dtype=np.float32)], colors=[_rgba(color)],
                                        radii=radius_m), static=True)

    def log_trajectory(self, name: str, times_s: np.ndarray, xyz: np.ndarray,
                       series: dict[str, np.ndarray] | None = None, color=(1.0, 0.4, 0.1)) -> None:
        """An executed trajectory: the whole track (static) plus the pose on the ``sim_time``
        timeline and scalar series (e.g. speed [m/s], locomotion L) as plots."""
        xyz = np.asarray(xyz, dtype=np.float32)
        times_s = np.asarray(times_s, dtype=np.float64)
        self.stream.log(f"{VEHICLES}/{name}/track",
                        rr.LineStrips3D([xyz], colors=[_rgba(color)], radii=0.15), static=True)
        self.stream.send_columns(
            f"{VEHICLES}/{name}/pose",
            indexes=[rr.TimeColumn("sim_time", duration=times_s)],
            columns=rr.Points3D.columns(positions=xyz, radii=np.full(len(xyz), 0.8, np.float32)),
        )
        for key, values in (series or {}).items():
            self.stream.send_columns(
                f"{PLOTS}/{name}/{key}",
                indexes=[rr.TimeColumn("sim_time", duration=times_s)],
                columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)),
            )

    def log_frame(self, name: str, rgb: np.ndarray, depth: np.ndarray, position: np.ndarray,
                  rotation: np.ndarray, focal_px: float) -> None:
        """An RGB-D frame with its camera pose (camera looks along −z, +y up: OpenGL/MuJoCo)."""
        h, w = depth.shape
        path = f"{FRAMES}/{name}"
        self.stream.log(path, rr.Transform3D(translation=position, mat3x3=rotation))
        self.stream.log(path, rr.Pinhole(focal_length=float(focal_px), width=w, height=h,
                                         camera_xyz=rr.ViewCoordinates.RUB))
        self.stream.log(f"{path}/rgb", rr.Image(rgb))
        self.stream.log(f"{path}/depth", rr.DepthImage(np.nan_to_num(depth, nan=0.0), meter=1.0))

    def log_text(self, name: str, markdown: str) -> None:
        """A markdown note (e.g. a results table)."""
        self.stream.log(f"notes/{name}", rr.TextDocument(markdown, media_type="text/markdown"),
                        static=True)


def verify(path: str | Path) -> None:
    """Run ``rerun rrd verify`` on a file; raises ``RuntimeError`` with its output if it fails."""
    exe = Path(sys.executable).parent / "rerun"
    cmd = [str(exe) if exe.exists() else "rerun", "rrd", "verify", str(path)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    # rerun exits 0 on a file that is not an .rrd at all ("0 files verified"): check the count.
    if done.returncode != 0 or "1 file verified without error" not in done.stdout + done.stderr:
        raise RuntimeError(f"rerun rrd verify {path} failed:\n{done.stdout}{done.stderr}")


def log_experiment(result: ExperimentResult, world: World, maps: WorldMaps,
                   path: str | Path) -> None:
    """Write an experiment's rerun recording: terrain, the costmap layers and occupancy of
    ``maps``, every planned path and executed trajectory (with speed) on the ``sim_time``
    timeline."""
    colors = {"dgt": (0.1, 0.3, 1.0), "isotropic": (0.2, 0.8, 0.9), "single-task": (0.6, 0.2, 0.8),
              "slope": (1.0, 0.1, 0.1), "binary": (0.4, 0.4, 0.4)}
    with Recording(path, result.name) as rec:
        rec.log_terrain(world.heights, world.colors, world.grid)
        rec.log_occupancy(maps.occupancy)
        for (method, vehicle), cost in maps.costmaps.items():
            rec.log_costmap(cost, vehicle, method)
        for r in result.results:
            name = f"{r.task.method}/{r.task.vehicle}_{r.task.index}_{r.task.query.label}"
            if len(r.path):
                z = world.height_at(r.path[:, 0], r.path[:, 1]) + 0.5
                rec.log_path(name, np.column_stack([r.path[:, :2], z]),
                             colors.get(r.task.method, (1, 1, 1)))
            if len(r.trajectory):
                rec.log_trajectory(name, r.trajectory[:, 0], r.trajectory[:, 1:4],
                                   {"speed_mps": r.speed})
        rec.log_text("results", result.markdown(PAPER.get(result.name)))
