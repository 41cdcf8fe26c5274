"""rerun logging: the writer of every ``.rrd`` recording (entity paths and blueprints:
:mod:`dgt_lib.viz.recording_layout`).

Library stages never import rerun; notebooks and experiment runners hand their
arrays to a :class:`Recording`, which writes a ``.rrd`` file that opens in the
viewer (``rerun data/<profile>/seed-<s>/runs/NAME.rrd``, or inside a notebook with
:func:`show`) on a layout built from what that recording logged: every entity is in
some view, and the blueprint, selection and time panels are open.

Entity tree (``world`` is RIGHT_HAND_Z_UP: x east, y north, z up, metres)::

    world/terrain                              terrain mesh coloured like the BEV RGB
    world/frames/<name>                        camera poses of RGB-D frames (Pinhole + images)
    world/paths/<name>                         planned paths, drawn on the terrain
    world/vehicle/<name>/{track,pose}          executed track; the vehicle as an oriented box
    world/costmap/<vehicle>/<method>/heading_<k>   cost layer θ_k = 2πk/K, a colormapped
                                               grid in metres, level above the terrain
    maps/bev/{rgb,height,std,gradient}         BEV channels as (colormapped) images, north up
    maps/bev/observed, maps/occupancy          masks with labelled classes
    plots/<name>/<series>                      scalars over time (speed, locomotion …)
    notes/<name>                               markdown (results tables, summaries)

Timelines: ``sim_time`` (each run's own simulated seconds), ``elapsed`` (runs back to
back in the order logged, so trials play one at a time: the time panel opens on it) and
``trial`` (the run's index: step through runs, each shown where it ended).

The recording id is ``<name>/<profile>/seed-<seed>`` so recordings of different profiles
or seeds opened together stay apart; the application id ``dgt-kit-<name>`` keeps one
blueprint per kind of recording.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
from matplotlib import colormaps

from dgt_lib.core import artifacts
from dgt_lib.core.config import Profile
from dgt_lib.core.geometry import GridSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.paper import PAPER
from dgt_lib.mapping.occupancy import FREE, OCCUPIED, UNOBSERVED
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.viz.recording_layout import (
    BEV,
    BEV_NAMES,
    BEV_TITLES,
    COSTMAPS,
    FRAMES,
    NOTES,
    OCCUPANCY,
    PATHS,
    PLOTS,
    TERRAIN,
    VEHICLES,
    WORLD,
    Layout,
)
from dgt_lib.world.worlds import World

if TYPE_CHECKING:  # an annotation only: importing it pulls in MPPI and the trials (~0.7 s)
    from dgt_lib.evaluation.experiments import ExperimentResult

COSTMAP_ABOVE_TERRAIN_M = 1.0
"""Costmap layers lie flat this far above the highest terrain point, over the terrain."""
TRIAL_GAP_S = 1.0
"""Pause between consecutive runs on the ``elapsed`` timeline [s]."""
METHOD_COLORS = {"dgt": (0.1, 0.3, 1.0), "isotropic": (0.2, 0.8, 0.9),
                 "single-task": (0.6, 0.2, 0.8), "slope": (1.0, 0.1, 0.1),
                 "binary": (0.4, 0.4, 0.4)}
_MASK_CLASSES = {  # class id → (label, colour) of the occupancy map and the observed mask
    OCCUPANCY: [(FREE, "free", (40, 160, 60)), (OCCUPIED, "occupied", (200, 40, 40)),
                (UNOBSERVED, "unobserved", (90, 90, 90))],
    f"{BEV}/observed": [(0, "unobserved", (90, 90, 90)), (1, "observed", (40, 160, 60))],
}


def recording_id(name: str, profile: Profile) -> str:
    """``<name>/<profile>/seed-<seed>``: unique per recording, profile and run seed."""
    return f"{name}/{profile.name}/seed-{profile.seed}"


def application_id(name: str) -> str:
    """``dgt-kit-<name>``: recordings of one kind share a blueprint in the viewer."""
    return "dgt-kit-" + re.sub(r"[^A-Za-z0-9_-]", "_", name)


def _map_image(array: np.ndarray) -> np.ndarray:
    """A grid array (rows grow with y) as an image (row 0 at the top = north up)."""
    return np.ascontiguousarray(np.flip(array, axis=0))


def _rgba(color) -> list[int]:
    c = np.asarray(color, dtype=np.float64)
    if c.max() <= 1.0:
        c = c * 255.0
    c = np.clip(np.rint(c), 0, 255).astype(int).tolist()
    return c + [255] * (4 - len(c))


def _colormapped(layer: np.ndarray, observed: np.ndarray) -> tuple[np.ndarray, float, float]:
    """A float grid as a viridis RGB image (north up) over its observed range (lo, hi);
    unobserved cells black."""
    values = layer[observed] if observed.any() else np.zeros(1)
    lo, hi = float(np.min(values)), float(np.max(values))
    rgb = colormaps["viridis"]((layer - lo) / max(hi - lo, 1e-9))[..., :3]
    rgb[~observed] = 0.0
    return _map_image((rgb * 255).astype(np.uint8)), lo, hi


def _yaw_quaternions(yaw: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions (x, y, z, w) of rotations by yaw [rad] about +z."""
    half = 0.5 * np.asarray(yaw, dtype=np.float64)
    q = np.zeros((len(half), 4), np.float32)
    q[:, 2], q[:, 3] = np.sin(half), np.cos(half)
    return q


def motion_yaw(xy: np.ndarray) -> np.ndarray:
    """Heading [rad] of travel at each of N positions (N, 2) [m]: the direction to the next
    position that differs. Stops and the last position keep the previous heading; before
    the first move, the first heading driven (0 if it never moves)."""
    xy = np.asarray(xy, dtype=np.float64)
    step = np.diff(xy, axis=0)
    is_move = np.hypot(step[:, 0], step[:, 1]) > 1e-6
    if not is_move.any():
        return np.zeros(len(xy))
    heading = np.arctan2(step[:, 1], step[:, 0])
    index = np.arange(len(step))
    latest = np.maximum.accumulate(np.where(is_move, index, -1))  # latest move at or before
    yaw = heading[np.where(latest >= 0, latest, np.argmax(is_move))]
    return np.append(yaw, yaw[-1])


class Recording:
    """A rerun recording written to a ``.rrd`` file. Use as a context manager::

        with Recording(path, "experiment1", profile) as rec:
            rec.log_terrain(heights, colors, grid)
            rec.log_path("dgt", path_xyz)

    The blueprint is built from what was logged and the file completed (flushed) when
    the ``with`` block ends. Until then rerun writes a hidden file beside ``path``, renamed
    over it when complete: a recording stopped half-way (Ctrl-C, a crash) leaves ``path``
    as it was, never half a recording.
    """

    def __init__(self, path: str | Path, name: str, profile: Profile):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.recording_id = recording_id(name, profile)
        self.stream = rr.RecordingStream(application_id(name), recording_id=self.recording_id)
        self._partial = self.path.with_name(f".{self.path.name[:80]}.{os.getpid()}.partial.rrd")
        self.stream.save(str(self._partial))
        self.layout = Layout()
        self._terrain_top_m = 0.0
        self._elapsed_s = 0.0
        self._log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP)

    # -- life cycle -------------------------------------------------------
    def close(self) -> Path:
        """Write the logged data, then the blueprint built from it; close the file and
        return its path."""
        self.stream.flush()
        self.stream.send_blueprint(self.layout.blueprint())
        self.stream.flush()
        self.stream.disconnect()
        if self._partial.exists():  # (a second close finds it renamed)
            artifacts.fsync_path(self._partial)
            os.replace(self._partial, self.path)
            artifacts.fsync_path(self.path.parent)
        return self.path

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _log(self, path: str, *archetypes, static: bool = True) -> None:
        self.layout.entities.add(path)
        self.stream.log(path, *archetypes, static=static)

    def _log_at(self, path: str, time_s: float | None, *archetypes) -> None:
        """Log static (time_s None) or at ``time_s`` [s] on ``sim_time`` and ``elapsed``
        (a recording of one run, which starts at 0 on both)."""
        if time_s is None:
            self._log(path, *archetypes)
            return
        self.stream.set_time("sim_time", duration=float(time_s))
        self.stream.set_time("elapsed", duration=float(time_s))
        self._log(path, *archetypes, static=False)

    def _send(self, path: str, indexes, columns) -> None:
        self.layout.entities.add(path)
        self.stream.send_columns(path, indexes=indexes, columns=columns)

    # -- static maps ------------------------------------------------------
    def log_terrain(self, heights: np.ndarray, colors: np.ndarray | None, grid: GridSpec,
                    *, max_cells: int = 200_000) -> None:
        """A coloured triangle mesh of a height grid (H, W) [m]; colours (H, W, 3) in 0..1.

        Grids larger than ``max_cells`` are subsampled for the viewer.
        """
        step = max(1, int(np.ceil(np.sqrt(heights.size / max_cells))))
        h = np.asarray(heights, dtype=np.float32)[::step, ::step]
        self._terrain_top_m = max(self._terrain_top_m, float(np.nanmax(h)))
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
        self._log(TERRAIN, rr.Mesh3D(vertex_positions=verts, triangle_indices=tris,
                                     vertex_colors=vcols))

    def _log_mask(self, path: str, mask: np.ndarray) -> None:
        classes = [rr.AnnotationInfo(id=i, label=label, color=color)
                   for i, label, color in _MASK_CLASSES[path]]
        self._log(path, rr.AnnotationContext(classes),
                  rr.SegmentationImage(_map_image(mask.astype(np.uint8))))

    def log_bev(self, channels: np.ndarray, observed: np.ndarray) -> None:
        """The six BEV channels (6, H, W) (R, G, B, H̄, σ_H, ‖∇H̄‖) and the observed mask,
        as images, north up; H̄, σ_H and ‖∇H̄‖ in viridis (dark → yellow) over their
        observed range, which the view's name gives; unobserved cells black."""
        observed = np.asarray(observed, bool)
        rgb = np.clip(np.moveaxis(channels[:3], 0, -1), 0, 1)
        self._log(f"{BEV}/rgb", rr.Image(_map_image((rgb * 255).astype(np.uint8))))
        self.layout.titles[f"{BEV}/rgb"] = "BEV R, G, B"
        for name, layer in zip(BEV_NAMES[1:], channels[3:6], strict=True):
            image, lo, hi = _colormapped(np.asarray(layer, np.float64), observed)
            self._log(f"{BEV}/{name}", rr.Image(image))
            self.layout.titles[f"{BEV}/{name}"] = f"BEV {BEV_TITLES[name]} {lo:.3g}…{hi:.3g}"
        self._log_mask(f"{BEV}/observed", observed)
        self.layout.titles[f"{BEV}/observed"] = "BEV observed"


    def log_costmap(self, costmap: np.ndarray, grid: GridSpec, vehicle: str,
                    method: str = "dgt", *, time_s: float | None = None) -> None:
        """A directional costmap (K, H, W) in [0, 1]: one grid map per heading
        θ_k = 2πk/K, in metres on ``grid``, viridis (0 dark, 1 yellow), lying flat
        ``COSTMAP_ABOVE_TERRAIN_M`` above the terrain's highest point. With ``time_s``
        [s] it is the costmap from that time on (a map growing during a run)."""
        base = f"{COSTMAPS}/{vehicle}/{method}"
        h, w = grid.shape
        fmt = rr.components.ImageFormat(width=w, height=h, color_model="L",
                                        channel_datatype="F32")
        z = self._terrain_top_m + COSTMAP_ABOVE_TERRAIN_M
        for k, layer in enumerate(costmap):
            data = _map_image(np.clip(np.asarray(layer, np.float32), 0.0, 1.0))
            self._log_at(f"{base}/heading_{k}", time_s, rr.GridMap(
                data=data.tobytes(), format=fmt, cell_size=grid.resolution,
                translation=[*grid.origin_xy, z], colormap="viridis", opacity=0.85))
        self.layout.costmaps[(vehicle, method)] = len(costmap)

    def log_occupancy(self, occupancy: np.ndarray) -> None:
        """Occupancy (H, W): 0 free, 1 occupied, 2 unobserved (labelled classes)."""
        self._log_mask(OCCUPANCY, occupancy)

    # -- paths and trajectories -------------------------------------------
    def log_path(self, name: str, xyz: np.ndarray, color=(0.1, 0.3, 1.0),
                 radius_m: float = 0.3, *, time_s: float | None = None) -> None:
        """A planned path (N, 3) world points [m] (z already on the terrain, plus
        clearance); with ``time_s`` [s] the path followed from that time on (replanning)."""
        self._log_at(f"{PATHS}/{name}", time_s, rr.LineStrips3D(
            [np.asarray(xyz, dtype=np.float32)], colors=[_rgba(color)], radii=radius_m))

    def log_trajectory(self, name: str, times_s: np.ndarray, xyz: np.ndarray,
                       series: dict[str, np.ndarray] | None = None, color=(1.0, 0.4, 0.1),
                       *, vehicle: str, yaw: np.ndarray | None = None) -> None:
        """An executed run: the whole track (static), the vehicle as a box of its size
        (length × width × height [m]) turned by yaw [rad] (default: the direction of
        travel) and scalar series (e.g. speed [m/s], locomotion L) as plots.

        Each call is the next run: on ``sim_time`` it starts at its own t = 0, on
        ``elapsed`` after the previous run, on ``trial`` at the run's index."""
        xyz = np.asarray(xyz, dtype=np.float32)
        times_s = np.asarray(times_s, dtype=np.float64)
        if not len(times_s):
            return
        trial, self.layout.runs = self.layout.runs, self.layout.runs + 1
        start = self._elapsed_s - float(times_s[0])
        self._elapsed_s = start + float(times_s[-1]) + TRIAL_GAP_S
        indexes = [rr.TimeColumn("sim_time", duration=times_s),
                   rr.TimeColumn("elapsed", duration=start + times_s),
                   rr.TimeColumn("trial", sequence=np.full(len(times_s), trial))]
        spec = get_vehicle(vehicle)
        half = np.array([spec.length_m, spec.width_m, spec.height_m], np.float32) / 2
        yaw = motion_yaw(xyz[:, :2]) if yaw is None else np.asarray(yaw, np.float64)
        self._log(f"{VEHICLES}/{name}/track",
                  rr.LineStrips3D([xyz], colors=[_rgba(color)], radii=0.15))
        self._send(f"{VEHICLES}/{name}/pose", indexes, rr.Boxes3D.columns(
            centers=xyz, half_sizes=np.tile(half, (len(xyz), 1)),
            quaternions=_yaw_quaternions(yaw), colors=np.tile(_rgba(color), (len(xyz), 1))))
        for key, values in (series or {}).items():
            self._send(f"{PLOTS}/{name}/{key}", indexes,
                       rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))

    def log_frame(self, name: str, rgb: np.ndarray, depth: np.ndarray, position: np.ndarray,
                  rotation: np.ndarray, focal_px: float) -> None:
        """An RGB-D frame with its camera pose (camera looks along −z, +y up: OpenGL/MuJoCo)."""
        h, w = depth.shape
        path = f"{FRAMES}/{name}"
        self._log(path, rr.Transform3D(translation=position, mat3x3=rotation),
                  rr.Pinhole(focal_length=float(focal_px), width=w, height=h,
                             camera_xyz=rr.ViewCoordinates.RUB))
        self._log(f"{path}/rgb", rr.Image(rgb))
        self._log(f"{path}/depth", rr.DepthImage(np.nan_to_num(depth, nan=0.0), meter=1.0))

    def log_text(self, name: str, markdown: str) -> None:
        """A markdown note (e.g. a results table), shown in a tab of its own."""
        self._log(f"{NOTES}/{name}", rr.TextDocument(markdown, media_type="text/markdown"))


def verify(path: str | Path) -> None:
    """Run ``rerun rrd verify`` on a file; raises ``RuntimeError`` with its output if it fails."""
    done = subprocess.run([_rerun_exe(), "rrd", "verify", str(path)],
                          capture_output=True, text=True)
    # rerun exits 0 on a file that is not an .rrd at all ("0 files verified"): check the count.
    if done.returncode != 0 or "1 file verified without error" not in done.stdout + done.stderr:
        raise RuntimeError(f"rerun rrd verify {path} failed:\n{done.stdout}{done.stderr}")


def _rerun_exe() -> str:
    exe = Path(sys.executable).parent / "rerun"
    return str(exe) if exe.exists() else "rerun"


def show(path: str | Path, *, height: int = 560) -> None:
    """Show a recording file inside the notebook: rerun's viewer as a widget, with the
    file's own blueprint and every panel open.

    Works offline: the viewer (JavaScript + WebAssembly) ships in ``rerun-notebook`` and
    is served from this machine (``RERUN_NOTEBOOK_ASSET=serve-local``, the default set
    here). For a Jupyter server on another machine, start it with
    ``RERUN_NOTEBOOK_ASSET=inline`` (the viewer travels inside the notebook) or open the
    file with ``rerun --serve-web FILE``. Under pytest (nbmake) there is no browser to
    draw into: the call only says which file it would show.
    """
    path = Path(path)
    if "PYTEST_CURRENT_TEST" in os.environ:
        print(f"rerun viewer (shown in Jupyter, not under pytest): {path}")
        return
    os.environ.setdefault("RERUN_NOTEBOOK_ASSET", "serve-local")
    from IPython.display import display

    with contextlib.redirect_stdout(io.StringIO()):  # the asset server's start-up chatter
        from rerun_notebook import Viewer

    viewer = Viewer(width="auto", height=height, panel_states={
        "blueprint": "expanded", "selection": "expanded", "time": "expanded"})
    display(viewer)
    viewer.send_rrd(path.read_bytes())


def log_experiment(result: ExperimentResult, world: World, maps: WorldMaps,
                   path: str | Path, profile: Profile) -> Layout:
    """Write an experiment's rerun recording: terrain, BEV map, costmap layers and
    occupancy of ``maps``, every planned path and executed trial (with speed) one after
    another on the ``elapsed`` timeline, and the results table. Returns its layout (what
    it logged, the views that show it)."""
    with Recording(path, result.name, profile) as rec:
        rec.log_terrain(world.heights, world.colors, world.grid)
        rec.log_bev(maps.bev.channels, maps.bev.observed)
        rec.log_occupancy(maps.occupancy)
        for (method, vehicle), cost in maps.costmaps.items():
            rec.log_costmap(cost, maps.grid, vehicle, method)
        for r in result.results:
            name = f"{r.task.method}/{r.task.vehicle}_{r.task.index}_{r.task.query.label}"
            color = METHOD_COLORS.get(r.task.method, (1, 1, 1))
            if len(r.path):
                z = world.height_at(r.path[:, 0], r.path[:, 1]) + 0.5
                rec.log_path(name, np.column_stack([r.path[:, :2], z]), color)
            if len(r.trajectory):
                rec.log_trajectory(name, r.trajectory[:, 0], r.trajectory[:, 1:4],
                                   {"speed_mps": r.speed}, color, vehicle=r.task.vehicle)
        rec.log_text("results", result.markdown(PAPER.get(result.name)))
    return rec.layout


def experiment_recording(result: ExperimentResult, profile: Profile) -> Path:
    """``runs/<stem>.rrd`` of an experiment in the profile's data directory
    (``experiment_stem``: a variant's has its own), written by :func:`log_experiment` when
    missing or older than its results or than this module or ``recording_layout.py`` (the
    code that lays it out); returns its path."""
    from dgt_lib.stages.costmaps import ensure_world_costmaps
    from dgt_lib.stages.experiments import experiment_stem
    from dgt_lib.stages.paths import data_dir
    from dgt_lib.viz import recording_layout
    from dgt_lib.world.terrain import get_world

    out, stem = data_dir(profile), experiment_stem(result.name, profile)
    rrd = out / "runs" / f"{stem}.rrd"
    pkl = out / "experiments" / f"{stem}.pkl"
    sources = [p for p in (pkl, Path(__file__), Path(recording_layout.__file__)) if p.exists()]
    if not rrd.exists() or rrd.stat().st_mtime < max(p.stat().st_mtime for p in sources):
        vehicles = tuple(sorted({r.task.vehicle for r in result.results}))
        maps = ensure_world_costmaps(result.world, vehicles, profile, progress=False)
        log_experiment(result, get_world(result.world, profile), maps, rrd, profile)
    return rrd
