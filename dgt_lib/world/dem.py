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

A DEM has no colour, and none is invented: its world is one grey
(:func:`~dgt_lib.world.worlds.no_imagery`) and mapped by a geometry-only model, unless an
orthophoto is given (:func:`read_image`: any 8-bit RGB GeoTIFF covering the DEM,
reprojected and resampled to its grid), which becomes the ground's colour the survey
camera sees.
"""

from __future__ import annotations

import functools
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dgt_lib.world.worlds import HeightmapError, World, from_heightmap, no_imagery

DEM_SUFFIXES: tuple[str, ...] = (".tif", ".tiff", ".asc")
"""File suffixes read as DEMs (GeoTIFF, ESRI ASCII grid) rather than plain height maps."""

NODATA_POLICIES: tuple[str, ...] = ("error", "crop")

MAX_DEM_CELLS = 4_000_000
"""Most height cells a DEM may become (2000 × 2000: 800 m × 800 m at 0.4 m): the BEV survey
and the costmaps grow with the area, and a 30 m DEM tile resampled to 0.4 m would not fit
in memory. A larger DEM is an error that says to crop it first."""

MAX_SOURCE_CELLS = 64_000_000
"""Most cells a DEM file may hold to be read (8000 × 8000): its band is read as float32
(4 bytes a cell) with a mask and a NaN-filled copy, about 10 bytes a cell, 640 MB at this
limit, which a laptop holds; a 20000² tile (4 GB as float64) is refused from its header,
before any cell is read."""


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

            given = _pairs(x, y)
            try:
                x, y = (np.asarray(v) for v in transform(self.source_crs, self.crs, x, y))
            except _gdal_errors() as exc:
                raise ValueError(f"coordinates {given} cannot be converted from the DEM's "
                                 f"CRS: {_one_line(exc)}") from None
            if not (np.isfinite(x).all() and np.isfinite(y).all()):
                raise ValueError(f"coordinates {given} lie outside where the DEM's CRS is "
                                 "defined (a latitude beyond ±90°?)")
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


def read_dem(path: str | Path, resolution_m: float, *, nodata: str = "error",
             band: int | None = None, log: Callable[[str], None] | None = None) -> Dem:
    """Read a GeoTIFF / ESRI ASCII DEM and resample it to ``resolution_m`` [m/cell] in a
    metric CRS (module docstring). ``band``: which band holds the heights (1-based; a file
    of several bands without it uses band 1 and says so through ``log``, default stderr).
    Raises :class:`HeightmapError` (one line naming the file) for a missing, unreadable or
    truncated file, a malformed ``.asc`` number (naming its line), a grid too large to map
    (said from the header, before any cell is read), no-data cells under
    ``nodata="error"`` (naming how many), or a DEM left with no valid cells."""
    if nodata not in NODATA_POLICIES:
        raise ValueError(f"nodata must be one of {NODATA_POLICIES}, got {nodata!r}")
    rasterio = import_rasterio()
    p = Path(path)
    if not p.is_file():
        raise HeightmapError(f"DEM file not found: {p}")
    if p.suffix.lower() == ".asc":
        check_ascii_grid(p)
    try:
        with rasterio.open(p) as src:
            index = _band(src, p, band, log)
            grid = _target_grid(src, p, float(resolution_m))
            _say_if_coarse(src, p, grid[0], log)
            out, source_crs = _resample(src, p, index, nodata, grid)
    except _gdal_errors() as exc:
        raise HeightmapError(f"cannot read {p} as a DEM: {_one_line(exc)}") from None
    dst_crs, dst_transform, res = grid[0], grid[1], float(resolution_m)
    rows, cols = largest_valid_rectangle(np.isfinite(out))
    if rows.stop <= rows.start:
        raise HeightmapError(f"{p} has no valid height cells")
    north_up = out[rows, cols]
    west = dst_transform.c + cols.start * res
    south = dst_transform.f - rows.stop * res
    crs_wkt = None if dst_crs is None else dst_crs.to_wkt()
    return Dem(north_up[::-1].astype(np.float32), res,
               Georeference(crs_wkt, (float(west), float(south)), source_crs))


def _gdal_errors() -> tuple[type[BaseException], ...]:
    """What rasterio, GDAL and PROJ raise for a bad file or coordinate."""
    import rasterio.errors

    errors: tuple[type[BaseException], ...] = (rasterio.errors.RasterioError,
                                               rasterio.errors.CRSError)
    try:
        from rasterio._err import CPLE_BaseError

        errors += (CPLE_BaseError,)
    except ImportError:  # another rasterio layout: its public errors still count
        pass
    return errors


def _pairs(x: np.ndarray, y: np.ndarray) -> str:
    return ", ".join(f"({a:g}, {b:g})" for a, b in zip(x, y, strict=True))


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _band(src, p: Path, band: int | None, log: Callable[[str], None] | None) -> int:
    """The 1-based band to read; says which when the file has several and none was asked."""
    if band is not None and not 1 <= band <= src.count:
        raise HeightmapError(f"{p} has {src.count} band(s): --band {band} is not one of them")
    if band is None and src.count > 1:
        (log or _stderr)(f"[dgt] {p} has {src.count} bands: reading heights from band 1 "
                         "(--band N reads another)")
    return band or 1


@functools.cache  # each line once per process: a DEM loaded again says nothing new
def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _target_grid(src, p: Path, res: float):
    """(metric CRS or None, transform, width, height) of the resampled grid, from the
    header alone; :class:`HeightmapError` when it or the file's own grid is too large."""
    from rasterio.transform import Affine
    from rasterio.warp import calculate_default_transform

    if src.width * src.height > MAX_SOURCE_CELLS:
        raise HeightmapError(
            f"{p} has {src.height} × {src.width} cells, more than the {MAX_SOURCE_CELLS:,} "
            "the kit reads; crop or coarsen it first (e.g. gdal_translate -projwin, -tr)")
    b = src.bounds
    if not (b.right > b.left and b.top > b.bottom and all(map(math.isfinite, b))):
        raise HeightmapError(f"{p} has no extent (bounds {tuple(b)}): check its cell size")
    dst_crs = _metric_crs(src)
    if dst_crs is None:  # no CRS: the file's units, resampled on its own axes
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
    return dst_crs, dst_transform, width, height


COARSE_DEM_M = 5.0
"""A DEM cell wider than this [m] is coarser than a vehicle: said once when it is read."""


def native_cell_m(src, dst_crs) -> float:
    """The file's own cell size in the metric CRS it is mapped in [m] (in its own units
    without a CRS): the width of the planar facets resampling draws between its samples."""
    if dst_crs is None:
        return float(abs(src.res[0]))
    from rasterio.warp import calculate_default_transform

    transform, _, _ = calculate_default_transform(src.crs, dst_crs, src.width, src.height,
                                                  *src.bounds)
    return float(abs(transform.a))


def _say_if_coarse(src, p: Path, dst_crs, log: Callable[[str], None] | None) -> None:
    """One line when the DEM's cells are coarser than a vehicle (:data:`COARSE_DEM_M`)."""
    cell = native_cell_m(src, dst_crs)
    if cell > COARSE_DEM_M:
        (log or _stderr)(
            f"[dgt] {p}: its cells are {cell:.0f} m across, coarser than a vehicle: resampled, "
            f"the terrain is planar facets {cell:.0f} m wide with slope steps at their edges, "
            "so costs and plans follow those facets, not relief smaller than them; a DEM of "
            f"a few metres or finer (lidar) shows what a vehicle meets")


def _resample(src, p: Path, index: int, nodata: str, grid) -> tuple[np.ndarray, str | None]:
    """Band ``index`` read (float32), checked for no-data, resampled onto ``grid``
    (:func:`_target_grid`): the (H, W) float64 heights, NaN outside the DEM, and the
    file's CRS as WKT."""
    from rasterio.warp import Resampling, reproject

    dst_crs, dst_transform, width, height = grid
    band = src.read(index, masked=True).astype(np.float32)
    invalid = np.ma.getmaskarray(band) | ~np.isfinite(band.filled(np.nan))
    if nodata == "error" and invalid.any():
        raise HeightmapError(
            f"{p} has {int(invalid.sum())} no-data cells of {invalid.size}: fill them "
            "(e.g. gdal_fillnodata.py) or keep the largest valid rectangle with "
            "--nodata crop")
    source = np.where(invalid, np.float32(np.nan), band.filled(np.nan))
    out = np.full((height, width), np.nan, np.float64)
    # without a CRS both sides share a stand-in one: GDAL then only resamples
    crs = dst_crs if dst_crs is not None else "EPSG:3857"
    reproject(source, out, src_transform=src.transform, src_crs=src.crs or crs,
              dst_transform=dst_transform, dst_crs=crs,
              src_nodata=np.nan, dst_nodata=np.nan, resampling=Resampling.bilinear)
    return out, None if src.crs is None else src.crs.to_wkt()


ASCII_HEADER_KEYS: tuple[str, ...] = ("ncols", "nrows", "xllcorner", "xllcenter", "yllcorner",
                                      "yllcenter", "cellsize", "dx", "dy", "nodata_value")


def check_ascii_grid(p: Path) -> None:
    """Read an ESRI ASCII grid strictly before GDAL does (GDAL reads ``2x`` as 2 and ``abc``
    as 0): a positive whole ``ncols``/``nrows`` within :data:`MAX_SOURCE_CELLS`, a finite
    cell size > 0, and exactly ``nrows`` × ``ncols`` numbers; else :class:`HeightmapError`
    naming the file and the line."""
    header: dict[str, str] = {}
    try:
        with open(p, encoding="ascii", errors="strict") as f:
            line_no, line = _ascii_header(f, p, header)
            ncols, nrows = _ascii_size(p, header)
            count = 0
            while line:
                values = line.split()
                try:
                    np.array(values, dtype=np.float64)
                except ValueError:
                    bad = next(v for v in values if not _is_number(v))
                    raise HeightmapError(f"{p} line {line_no}: {bad[:40]!r} is not a "
                                         "number") from None
                count += len(values)
                line, line_no = f.readline(), line_no + 1
    except UnicodeDecodeError as exc:
        raise HeightmapError(f"{p} is not an ESRI ASCII grid: byte {exc.start} is not "
                             "ASCII text") from None
    if count != ncols * nrows:
        raise HeightmapError(f"{p} holds {count} numbers; its header declares "
                             f"{nrows} × {ncols} = {nrows * ncols}")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _ascii_header(f, p: Path, header: dict[str, str]) -> tuple[int, str]:
    """The header's ``key value`` lines into ``header``; (number, text) of the first
    line of numbers."""
    line_no, line = 1, f.readline()
    while line:
        parts = line.split()
        if parts and parts[0].lower() in ASCII_HEADER_KEYS:
            if len(parts) != 2:
                raise HeightmapError(f"{p} line {line_no}: a header line is `key value`, "
                                     f"got {line.strip()[:60]!r}")
            header[parts[0].lower()] = parts[1]
        elif parts:
            break
        line, line_no = f.readline(), line_no + 1
    return line_no, line


def _ascii_size(p: Path, header: dict[str, str]) -> tuple[int, int]:
    """(ncols, nrows) of a parsed header, checked with its cell size."""
    try:
        ncols, nrows = int(header["ncols"]), int(header["nrows"])
        cell = float(header.get("cellsize", header.get("dx", "nan")))
    except (KeyError, ValueError) as exc:
        raise HeightmapError(f"{p}: its header needs whole ncols and nrows and a cell size "
                             f"({_one_line(exc)})") from None
    if ncols < 1 or nrows < 1 or ncols * nrows > MAX_SOURCE_CELLS:
        raise HeightmapError(f"{p} declares {nrows} × {ncols} cells: from 1 to "
                             f"{MAX_SOURCE_CELLS:,} cells can be read")
    if not (math.isfinite(cell) and cell > 0):
        raise HeightmapError(f"{p}: cellsize {header.get('cellsize', header.get('dx'))} "
                             "must be a finite number > 0")
    return ncols, nrows


def load_dem(path: str | Path, resolution_m: float, *, nodata: str = "error",
             name: str | None = None, band: int | None = None,
             image: str | Path | None = None) -> tuple[World, Georeference]:
    """A :class:`World` from a DEM file (:func:`read_dem` → :func:`from_heightmap`) and the
    :class:`Georeference` that places it on Earth; its colours are ``image``'s
    (:func:`read_image`), or one grey without one (:func:`~dgt_lib.world.worlds.no_imagery`)."""
    dem = read_dem(path, resolution_m, nodata=nodata, band=band)
    colors = read_image(image, dem) if image is not None else no_imagery(dem.heights.shape)
    world = from_heightmap(dem.heights, dem.resolution, colors=colors,
                           name=name or Path(path).stem)
    return world, dem.georef


def read_image(path: str | Path, dem: Dem) -> np.ndarray:
    """An orthophoto (a GeoTIFF of 3 bands, 8-bit RGB) on ``dem``'s grid: (H, W, 3) uint8,
    row 0 the south edge, reprojected from its CRS to the DEM's metric one and resampled
    (bilinear); a file without a CRS is taken to be in the DEM file's coordinates. Raises
    :class:`HeightmapError` (one line naming the file) for a missing or unreadable file,
    another band count or type, or an image that does not cover the whole DEM."""
    rasterio = import_rasterio()
    p = Path(path)
    if not p.is_file():
        raise HeightmapError(f"image file not found: {p}")
    try:
        with rasterio.open(p) as src:
            if src.count != 3 or set(src.dtypes) != {"uint8"}:
                raise HeightmapError(f"{p} has {src.count} band(s) of "
                                     f"{'/'.join(sorted(set(src.dtypes)))}: --image needs 3 "
                                     "bands of 8-bit RGB")
            rgb = _resample_image(src, dem)
    except _gdal_errors() as exc:
        raise HeightmapError(f"cannot read {p} as an image: {_one_line(exc)}") from None
    covered = np.isfinite(rgb).all(axis=0)
    if not covered.all():
        how = (f"covers only {math.floor(100 * covered.mean())} % of" if covered.any()
               else "does not overlap")
        raise HeightmapError(f"{p} {how} the DEM: --image must cover all of it (crop the "
                             "DEM to the image first, e.g. gdal_translate -projwin)")
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8).transpose(1, 2, 0)[::-1]


def _resample_image(src, dem: Dem) -> np.ndarray:
    """``src``'s three bands on ``dem``'s grid, north row first: (3, H, W) float32, NaN
    where the image has no data or does not reach."""
    from rasterio.transform import Affine
    from rasterio.warp import Resampling, reproject

    g, res = dem.georef, dem.resolution
    h, w = dem.heights.shape
    dst_transform = Affine(res, 0.0, g.origin[0], 0.0, -res, g.origin[1] + h * res)
    crs = g.crs if g.crs is not None else "EPSG:3857"  # no CRS: a stand-in, as _resample's
    src_crs = (src.crs if g.crs is not None else None) or g.source_crs or crs
    source = src.read(masked=True).astype(np.float32).filled(np.nan)
    out = np.full((3, h, w), np.nan, np.float32)
    reproject(source, out, src_transform=src.transform, src_crs=src_crs,
              dst_transform=dst_transform, dst_crs=crs, src_nodata=np.nan, dst_nodata=np.nan,
              resampling=Resampling.bilinear)
    return out


def is_dem_path(path: str | Path) -> bool:
    """Whether a file is read as a DEM (by its suffix: :data:`DEM_SUFFIXES`)."""
    return Path(path).suffix.lower() in DEM_SUFFIXES
