"""One planning query on any world: the engine of ``dgt plan``.

Resolves the world once — a kit world's name, a ``.npy``/``.png`` height map or a DEM
(GeoTIFF, ESRI ASCII grid: :mod:`dgt_lib.world.dem`) — with the profile whose models map
it (:func:`costmap_profile`) and, for a DEM, start and goal given in the file's CRS; then
:func:`dgt_lib.app.query.plan_on_world` checks, maps, plans and reports::

    report = plan_query("hill", "carla_cola", (30, 14, 0.8), (30, 96), method="dgt")
    print(report.summary())
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dgt_lib.app.query import CostmapSource, QueryReport, plan_on_world
from dgt_lib.core.config import Profile, as_profile
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.mapping.methods import METHODS
from dgt_lib.world.dem import Georeference, is_dem_path, load_dem
from dgt_lib.world.terrain import WORLD_NAMES, get_world
from dgt_lib.world.worlds import World, load_heightmap


def load_world(world: str | World, profile: Profile, *, resolution_m: float = 0.4,
               vertical_scale_m: float | None = None, nodata: str = "error",
               band: int | None = None, image: str | Path | None = None
               ) -> tuple[World, Georeference | None]:
    """A :class:`World` and, for a DEM, its :class:`~dgt_lib.world.dem.Georeference`.

    A DEM (GeoTIFF ``.tif``, ESRI ASCII grid ``.asc``) is resampled to the profile's
    ``worlds.hfield_resolution_m`` (:func:`~dgt_lib.world.dem.load_dem`; ``nodata``: what
    to do with its no-data cells; ``band``: which band holds heights; ``image``: an
    orthophoto for its colour, else it is one grey); a ``.npy``/``.png``
    heightmap has ``resolution_m``
    [m/pixel] and no georeference, nor does a kit world or a World."""
    if image is not None and not (isinstance(world, str) and is_dem_path(world)):
        raise ValueError("--image colours a DEM world (.tif / .asc); this world is not one")
    if isinstance(world, World):
        return world, None
    if world in WORLD_NAMES:
        return get_world(world, profile), None
    path = Path(world)
    if not path.exists():
        raise FileNotFoundError(f"{world!r} is neither a world ({', '.join(WORLD_NAMES)}) "
                                "nor an existing .npy/.png heightmap or .tif/.asc DEM file")
    if is_dem_path(path):
        return load_dem(path, profile.worlds.hfield_resolution_m, nodata=nodata, band=band,
                        image=image)
    if path.suffix.lower() == ".npy" and not _is_npy(path):
        raise ValueError(f"{world} is not a NumPy heightmap: a .npy file starts with "
                         "NumPy's header (np.save writes one); this one does not")
    return load_heightmap(path, resolution_m, vertical_scale_m=vertical_scale_m), None


def _is_npy(path: Path) -> bool:
    """Whether ``path`` starts with the ``.npy`` format's magic string, so that a text or
    pickle file renamed ``.npy`` is called what it is, not a pickle to allow."""
    with open(path, "rb") as f:
        return f.read(6) == b"\x93NUMPY"


def costmap_profile(world: str | World, method: str, profile: Profile,
                    image: str | Path | None = None) -> tuple[Profile, str]:
    """The profile whose models map ``world``, and the words saying what its costmap read.

    A DEM or height-map file without ``image`` has no colour to read: its costmap comes
    from the profile's geometry-only models (``train.inputs=geometry``, trained on the
    same dataset when first needed, cached beside the RGB-D ones); with ``image`` (a
    DEM's orthophoto), the RGB-D models read its colours. The slope and binary methods
    read heights alone."""
    if isinstance(world, str) and world not in WORLD_NAMES and image is None:
        if profile.train.inputs != "geometry":
            profile = profile.with_overrides({"train.inputs": "geometry"})
        return profile, "geometry only (no imagery)"
    if method in ("slope", "binary"):
        return profile, "geometry only (the method reads no colour)"
    seen = {"rgbd": "RGB-D", "geometry": "geometry only", "rgb": "RGB only"}[
        profile.train.inputs]
    if image is not None:
        return profile, f"{seen} with imagery from {Path(image).name}"
    if isinstance(world, str) and world in WORLD_NAMES:
        return profile, f"{seen} (the simulated world's colours)"
    return profile, f"{seen} (the world's colours)"


def crs_to_local(georef: Georeference | None, start, goal) -> tuple[tuple, tuple]:
    """Start (x, y, yaw) and goal (x, y) given in the DEM file's CRS → the world frame [m]
    (yaw is kept: it is measured in the world frame, from east). ValueError without a
    georeference (only a DEM has one)."""
    if georef is None:
        raise ValueError("coordinates in the file's CRS need a DEM (.tif / .asc) world")
    xs, ys = georef.to_local([start[0], goal[0]], [start[1], goal[1]])
    x, y = np.round(xs, 3), np.round(ys, 3)  # to the millimetre: the summary reads them
    return ((float(x[0]), float(y[0]), float(start[2])), (float(x[1]), float(y[1])))


def plan_query(world: str | World, vehicle: str | VehicleSpec, start, goal, *, method: str = "dgt",
               profile: Profile | str | None = None, drive: bool = False,
               resolution_m: float = 0.4, vertical_scale_m: float | None = None,
               out_dir: Path | None = None, progress: bool = True, crs_coords: bool = False,
               nodata: str = "error", source: CostmapSource | None = None,
               band: int | None = None, image: str | Path | None = None) -> QueryReport:
    """Plan (and optionally drive) one query on a world given by name, file or value
    (:func:`~dgt_lib.app.query.plan_on_world` does the work).

    start (x, y, yaw) [m, m, rad], goal (x, y) [m]; ``crs_coords``: their x, y are in a
    DEM file's CRS (:func:`crs_to_local`); ``nodata``, ``band``, ``image``: a DEM's no-data
    policy, band and orthophoto (:func:`load_world`); the models that map the world:
    :func:`costmap_profile`. ``vehicle``: a named vehicle's name or a spec
    (:func:`~dgt_lib.core.vehicle_range.resolve_vehicle` resolves a file); ``source``: the
    costmap of a vehicle that is not a named one.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
    prof, inputs = costmap_profile(world, method, as_profile(profile), image)
    spec = get_vehicle(vehicle)  # an unknown name: an error before any work
    w, georef = load_world(world, prof, resolution_m=resolution_m,
                           vertical_scale_m=vertical_scale_m, nodata=nodata, band=band,
                           image=image)
    if crs_coords:
        start, goal = crs_to_local(georef, start, goal)
    return plan_on_world(w, spec, start, goal, method=method, profile=prof, drive=drive,
                         out_dir=out_dir, progress=progress, source=source, inputs=inputs,
                         settings=as_profile(profile))  # the user's: the input is in the key
