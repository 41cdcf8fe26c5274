"""The engine of ``dgt costmap``: a world's directional costmap written for other tools.

The costmap is the one ``dgt plan`` uses, from the same cache
(:func:`~dgt_lib.stages.costmaps.ensure_world_costmaps`: built once, training first when
the profile has no model yet); the writers are :mod:`dgt_lib.mapping.export`::

    paths = export_costmap("dem.tif", "jeep", "jeep_costmap.tif", method="dgt")
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dgt_lib.app.plan_one import costmap_profile, load_world
from dgt_lib.app.query import training_notice
from dgt_lib.core.config import Profile, as_profile
from dgt_lib.core.outputs import check_output_path
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.mapping.export import nav2_stem, write_geotiff, write_nav2
from dgt_lib.mapping.methods import METHODS
from dgt_lib.stages.costmaps import ensure_world_costmaps
from dgt_lib.world.dem import import_rasterio
from dgt_lib.world.worlds import World

FORMATS: tuple[str, ...] = ("geotiff", "nav2")
"""``geotiff``: one multi-band GeoTIFF; ``nav2``: map_server PGM + YAML per layer."""


def export_costmap(world: str | World, vehicle: str, out: str | Path, *, method: str = "dgt",
                   fmt: str = "geotiff", profile: Profile | str | None = None,
                   resolution_m: float = 0.4, vertical_scale_m: float | None = None,
                   nodata: str = "error", progress: bool = True,
                   band: int | None = None, image: str | Path | None = None) -> list[Path]:
    """Write ``method``'s K-heading costmap of ``vehicle`` on ``world`` (a kit world, a
    heightmap or DEM file: :func:`~dgt_lib.app.plan_one.load_world`) to ``out`` in ``fmt``
    (:data:`FORMATS`), georeferenced when the world came from a DEM. Returns the files
    written (the GeoTIFF, or the YAML files). ``out`` is checked before any work
    (:func:`output_target`); ``band``: a DEM's band (:func:`~dgt_lib.world.dem.read_dem`);
    ``image``: a DEM's orthophoto. With ``progress``, says on stderr what the costmap
    read (:func:`~dgt_lib.app.plan_one.costmap_profile`: a DEM without imagery, geometry only)."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; valid formats: {', '.join(FORMATS)}")
    get_vehicle(vehicle)
    prof, read = costmap_profile(world, method, as_profile(profile), image)
    if fmt == "geotiff":
        import_rasterio()  # missing: a one-line error now, not after the costmap is built
    files = (() if isinstance(world, World) else (world,)) + ((image,) if image else ())
    target = output_target(out, fmt, f"{vehicle}_{method}", inputs=files)
    w, georef = load_world(world, prof, resolution_m=resolution_m,
                           vertical_scale_m=vertical_scale_m, nodata=nodata, band=band,
                           image=image)
    notice = training_notice(method, vehicle, prof)
    if progress and notice:
        print(notice, flush=True)
    if progress:
        print(f"[dgt] costmap input: {read}", file=sys.stderr, flush=True)
    maps = ensure_world_costmaps(w, (vehicle,), prof, methods=(method,), progress=progress)
    cost = maps.costmap(method, vehicle)
    if fmt == "geotiff":
        return [write_geotiff(target, cost, maps.occupancy, maps.grid, georef)]
    return write_nav2(target, cost, maps.occupancy, maps.grid)


def output_target(out: str | Path, fmt: str, name: str, *,
                  inputs: tuple[str | Path, ...] = ()) -> Path:
    """Where ``dgt costmap`` writes, checked before any work
    (:func:`~dgt_lib.core.outputs.check_output_path`: a one-line
    :class:`~dgt_lib.core.outputs.OutputPathError` for a directory that cannot take a
    file, a directory given as the GeoTIFF, a name too long, ``out`` equal to an input).
    A Nav2 ``out`` that is a directory (or ends in ``/``) gets its files inside it, named
    ``<name>_heading<k>…``; every file of the set is checked by its longest name."""
    if str(out).strip() == "":
        return check_output_path(out)
    if fmt == "geotiff":
        return check_output_path(out, inputs=inputs)
    stem = nav2_stem(out, name)
    check_output_path(f"{stem}_occupancy.yaml", what="--out", inputs=inputs)
    for k in (0, 99):  # the longest heading's name stands for every layer's
        check_output_path(f"{stem}_heading{k}.yaml", what="--out", inputs=inputs)
    return stem.with_name(stem.name + ".nav2")  # write_nav2 drops the suffix again


def run_command(args: argparse.Namespace, profile: Profile) -> int:
    """``dgt costmap`` (its options: ``dgt costmap --help``): prints the files written;
    exit status 0, or 2 with a one-line error for a bad world, file, method or format."""
    try:
        args.kept = (f"the cache's finished work; {args.out or '--out'} is its earlier file "
                     "(or none) or the whole new one, never a part")
        paths = export_costmap(args.world, args.vehicle, args.out, method=args.method,
                               fmt=args.fmt, profile=profile, resolution_m=args.resolution,
                               vertical_scale_m=args.vertical_scale, nodata=args.nodata,
                               band=args.band, image=args.image)
    except (FileNotFoundError, ValueError) as exc:
        print(f"dgt costmap: error: {exc}", file=sys.stderr)
        return 2
    for path in paths:
        print(path)
    return 0
