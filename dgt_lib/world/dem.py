"""Real terrain in: a digital elevation model (GeoTIFF, ESRI ASCII grid) as a :class:`World`.

A DEM is read with its georeference through rasterio (``pip install 'dgt-kit[geo]'``),
reprojected to metres when its coordinates are geographic (degrees: the UTM zone of the
DEM's centre), resampled (bilinear) to the profile's height-field resolution, and handed
to :func:`~dgt_lib.world.worlds.from_heightmap` like any height map. The world's frame is
the kit's: x east, y north, in metres from the map's south-west corner;
:class:`Georeference` converts between it and the file's coordinates.

No-data cells are never read as heights: a DEM with no-data cells inside its footprint is
an error by default (the kit's worlds have ground everywhere, and a hole filled with
invented heights would be planned over as real ground); ``nodata="crop"`` keeps the
largest rectangle of valid cells instead. The edges that reprojection leaves outside a
DEM's rotated footprint are always cropped: they were never part of the DEM. Heights are
taken to be metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dgt_lib.world.worlds import HeightmapError, World, from_heightmap

DEM_SUFFIXES: tuple[str, ...] = (".tif", ".tiff", ".asc")
"""File suffixes read as DEMs (GeoTIFF, ESRI ASCII grid) rather than plain height maps."""

NODATA_POLICIES: tuple[str, ...] = ("error", "crop")

MAX_DEM_CELLS = 4_000_000
"""Most height cells a DEM may become (2000 × 2000: 800 m × 800 m at 0.4 m): the BEV survey
and the costmaps grow with the area, and a 30 m DEM tile resampled to 0.4 m would not fit
in memory. A larger DEM is an error that says to crop it first."""


def import_rasterio():
    """rasterio, or a one-line error naming the extra that installs it."""
    try:
        import rasterio
    except ImportError:
        raise HeightmapError("reading or writing GeoTIFF / ESRI ASCII grids needs rasterio: "
                             "pip install 'dgt-kit[geo]'") from None
    return rasterio


@dataclass(frozen=True)
class Georeference:
    """Where a world lies on Earth: the world's (x, y) [m] is ``origin`` + (x, y) in ``crs``.

    crs: WKT of the metric CRS the world was built in (the file's own when projected,
    else a UTM zone), or None for a file without a CRS (then x, y are the file's units
    from its south-west corner). source_crs: WKT of the file's CRS (what
    ``--crs-coords`` coordinates are in)."""

    crs: str | None
    origin: tuple[float, float]
    source_crs: str | None

    def to_local(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Points in the file's CRS (e.g. lon, lat in degrees) → world x, y [m]."""
        x, y = np.atleast_1d(np.asarray(x, np.float64)), np.atleast_1d(np.asarray(y, np.float64))
        if self.source_crs is not None and self.source_crs != self.crs:
            from rasterio.warp import transform

            x, y = (np.asarray(v) for v in transform(self.source_crs, self.crs, x, y))
        return x - self.origin[0], y - self.origin[1]


@dataclass(frozen=True)
class Dem:
    """A DEM resampled for the kit: heights (H, W) float32 [m], row 0 the south edge,
    at ``resolution`` [m/cell], and its :class:`Georeference`."""

    heights: np.ndarray
    resolution: float
    georef: Georeference


def utm_epsg(lon_deg: float, lat_deg: float) -> int:
    """EPSG code of the WGS 84 UTM zone containing (lon, lat) [deg]: 326zz north, 327zz south."""
    zone = min(60, max(1, int(math.floor((lon_deg + 180.0) / 6.0)) + 1))
    return (32600 if lat_deg >= 0 else 32700) + zone


def _metric_crs(src):
    """The CRS to build the world in: the file's when it is projected in metres, else the
    UTM zone of the DEM's centre; None when the file has no CRS (its units are used)."""
    from rasterio.crs import CRS
    from rasterio.warp import transform

    if src.crs is None:
        return None
    if src.crs.is_projected and abs(src.crs.linear_units_factor[1] - 1.0) < 1e-9:
        return src.crs
    b = src.bounds
    lon, lat = transform(src.crs, "EPSG:4326", [(b.left + b.right) / 2],
                         [(b.bottom + b.top) / 2])
    return CRS.from_epsg(utm_epsg(lon[0], lat[0]))


def largest_valid_rectangle(valid: np.ndarray) -> tuple[slice, slice]:
    """Rows and columns of the largest axis-aligned rectangle of True cells (the
    histogram method: one pass over the rows, a stack over the columns)."""
    h, w = valid.shape
    heights = np.zeros(w + 1, np.int64)  # a 0 sentinel closes every run
    best, best_box = 0, (slice(0, 0), slice(0, 0))
    for r in range(h):
        heights[:w] = np.where(valid[r], heights[:w] + 1, 0)
        stack: list[int] = []
        for c in range(w + 1):
            while stack and heights[stack[-1]] >= heights[c]:
                top = stack.pop()
                left = stack[-1] + 1 if stack else 0
                area = int(heights[top]) * (c - left)
                if area > best:
                    best = area
                    best_box = (slice(r - int(heights[top]) + 1, r + 1), slice(left, c))
            stack.append(c)
    return best_box


def read_dem(path: str | Path, resolution_m: float, *, nodata: str = "error") -> Dem:
    """Read a GeoTIFF / ESRI ASCII DEM and resample it to ``resolution_m`` [m/cell] in a
    metric CRS (module docstring). Raises :class:`HeightmapError` for a missing or
    unreadable file, no-data cells under ``nodata="error"`` (naming how many), or a DEM
    left with no valid cells."""
    if nodata not in NODATA_POLICIES:
        raise ValueError(f"nodata must be one of {NODATA_POLICIES}, got {nodata!r}")
    rasterio = import_rasterio()
    from rasterio.transform import Affine
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    p = Path(path)
    if not p.is_file():
        raise HeightmapError(f"DEM file not found: {p}")
    try:
        src = rasterio.open(p)
    except rasterio.errors.RasterioIOError as exc:
        raise HeightmapError(f"cannot read {p} as a DEM: {exc}") from None
    with src:
        band = src.read(1, masked=True).astype(np.float64)
        invalid = np.ma.getmaskarray(band) | ~np.isfinite(band.filled(np.nan))
        if nodata == "error" and invalid.any():
            raise HeightmapError(
                f"{p} has {int(invalid.sum())} no-data cells of {invalid.size}: fill them "
                "(e.g. gdal_fillnodata.py) or keep the largest valid rectangle with "
                "--nodata crop")
        dst_crs = _metric_crs(src)
        source = np.where(invalid, np.nan, band.filled(np.nan))
        res = float(resolution_m)
        if dst_crs is None:  # no CRS: the file's units, resampled on its own axes
            b = src.bounds
            width = max(1, round((b.right - b.left) / res))
            height = max(1, round((b.top - b.bottom) / res))
            dst_transform = Affine(res, 0.0, b.left, 0.0, -res, b.top)
        else:
            dst_transform, width, height = calculate_default_transform(
                src.crs, dst_crs, src.width, src.height, *src.bounds, resolution=res)
        if width * height > MAX_DEM_CELLS:
            raise HeightmapError(
                f"{p} covers {width * res:.0f} m × {height * res:.0f} m: {height} × {width} "
                f"cells at {res} m, more than the {MAX_DEM_CELLS:,} the kit maps; crop it "
                "to the area to plan in first (e.g. gdal_translate -projwin)")
        out = np.full((height, width), np.nan, np.float64)
        # without a CRS both sides share a stand-in one: GDAL then only resamples
        crs = dst_crs if dst_crs is not None else "EPSG:3857"
        reproject(source, out, src_transform=src.transform, src_crs=src.crs or crs,
                  dst_transform=dst_transform, dst_crs=crs,
                  src_nodata=np.nan, dst_nodata=np.nan, resampling=Resampling.bilinear)
        source_crs = None if src.crs is None else src.crs.to_wkt()
    rows, cols = largest_valid_rectangle(np.isfinite(out))
    if rows.stop <= rows.start:
        raise HeightmapError(f"{p} has no valid height cells")
    north_up = out[rows, cols]
    west = dst_transform.c + cols.start * res
    south = dst_transform.f - rows.stop * res
    crs_wkt = None if dst_crs is None else dst_crs.to_wkt()
    return Dem(north_up[::-1].astype(np.float32), res,
               Georeference(crs_wkt, (float(west), float(south)), source_crs))


def load_dem(path: str | Path, resolution_m: float, *, nodata: str = "error",
             name: str | None = None) -> tuple[World, Georeference]:
    """A :class:`World` from a DEM file (:func:`read_dem` → :func:`from_heightmap`) and the
    :class:`Georeference` that places it on Earth."""
    dem = read_dem(path, resolution_m, nodata=nodata)
    world = from_heightmap(dem.heights, dem.resolution, name=name or Path(path).stem)
    return world, dem.georef


def is_dem_path(path: str | Path) -> bool:
    """Whether a file is read as a DEM (by its suffix: :data:`DEM_SUFFIXES`)."""
    return Path(path).suffix.lower() in DEM_SUFFIXES
