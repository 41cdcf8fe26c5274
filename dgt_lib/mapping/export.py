"""Directional costmaps out, in formats other tools open.

:func:`write_geotiff`: one multi-band GeoTIFF (QGIS, rasterio, GDAL): band k + 1 is the
cost layer of heading θ_k = 2πk/K (its description ``heading_k=k theta_deg=…``, the same
as band tags; the binary method's one isotropic layer says so), the last band the
occupancy map (0 free, 1 occupied, 2 unobserved), on the costmap's grid (its cells [m]). When
the world came from a DEM (a :class:`Georeference`) it is in the CRS the world was built
in: the DEM's own when projected, the UTM zone of its centre when in degrees (the map is
not warped back to degrees: its cells stay square metres). Otherwise it is in the world's
metric frame with no CRS.

:func:`write_nav2`: for ROS 2 Nav2's map_server, one PGM image + YAML per heading
(``mode: scale``: pixel 255·(1 − C), so 255 free … 0 lethal; occupied and unobserved
cells lethal) and one for the occupancy (``mode: trinary``: free, occupied, unknown),
``origin`` the south-west corner in the world frame [m].

Rows are flipped on the way out: both formats put the north edge first, the kit's grids
the south (docs/ARCHITECTURE.md → Conventions).

Every file is written atomically under a lock (:func:`~dgt_lib.core.artifacts.write_atomically`):
a writer killed half-way leaves the earlier file, and two writers of one path take turns.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dgt_lib.core.artifacts import build_lock, write_atomically
from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.occupancy import FREE, OCCUPIED
from dgt_lib.world.dem import Georeference, import_rasterio

TRINARY_FREE, TRINARY_OCCUPIED, TRINARY_UNKNOWN = 254, 0, 205
"""map_server's trinary pixel values (those of its own map saver)."""

TRINARY_THRESHOLDS = (0.65, 0.196)
"""(occupied_thresh, free_thresh) of the occupancy map: map_server's defaults."""

SCALE_THRESHOLDS = (0.999, 0.001)
"""(occupied_thresh, free_thresh) of the cost layers: only C = 1 is lethal, C = 0 free, and
map_server scales everything between linearly to 1..98."""


def heading_label(k: int, n_headings: int) -> str:
    """``heading_k=2 theta_deg=90.0``: band description of layer k of K; an isotropic
    costmap's one layer (K = 1: the binary method) is ``isotropic (every heading)``."""
    if n_headings == 1:
        return "isotropic (every heading)"
    return f"heading_k={k} theta_deg={360.0 * k / n_headings:.1f}"


def _check(cost: np.ndarray, occupancy: np.ndarray, grid: GridSpec) -> None:
    if cost.ndim != 3 or cost.shape[1:] != grid.shape or occupancy.shape != grid.shape:
        raise ValueError(f"cost must be (K, H, W) and occupancy (H, W) on the grid {grid.shape}, "
                         f"got {cost.shape} and {occupancy.shape}")


def north_up_transform(grid: GridSpec, georef: Georeference | None = None):
    """The affine transform of a grid's north-up image: its north-west corner, in the
    georeference's CRS when there is one, else in the world frame [m]."""
    from rasterio.transform import Affine

    ox, oy = georef.origin if georef is not None else (0.0, 0.0)
    x0, y0 = grid.origin_xy
    res = grid.resolution
    return Affine(res, 0.0, ox + x0, 0.0, -res, oy + y0 + grid.height * res)


def write_geotiff(path: str | Path, cost: np.ndarray, occupancy: np.ndarray, grid: GridSpec,
                  georef: Georeference | None = None) -> Path:
    """K cost layers + the occupancy as a (K + 1)-band float32 GeoTIFF (module docstring)."""
    rasterio = import_rasterio()
    _check(cost, occupancy, grid)
    k_layers, h, w = cost.shape
    bands = np.concatenate([cost, occupancy[None]]).astype(np.float32)[:, ::-1]
    path = Path(path)
    profile = {"driver": "GTiff", "height": h, "width": w, "count": k_layers + 1,
               "dtype": "float32", "transform": north_up_transform(grid, georef),
               "crs": None if georef is None else georef.crs}
    if np.isnan(bands).any():
        profile["nodata"] = float("nan")

    def write(tmp: Path) -> None:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(bands)
            for k in range(k_layers):
                dst.set_band_description(k + 1, heading_label(k, k_layers))
                if k_layers > 1:
                    dst.update_tags(k + 1, heading_k=k, theta_deg=f"{360.0 * k / k_layers:.1f}")
            dst.set_band_description(k_layers + 1, "occupancy 0=free 1=occupied 2=unobserved")
            dst.update_tags(k_layers + 1, layer="occupancy")

    return write_atomically(path, write)


def _write_pgm(path: Path, image: np.ndarray) -> None:
    """A binary greyscale PGM (P5, maxval 255) of a (H, W) uint8 image, row 0 at the top."""
    h, w = image.shape
    data = f"P5\n{w} {h}\n255\n".encode("ascii") + np.ascontiguousarray(image).tobytes()
    write_atomically(path, lambda tmp: tmp.write_bytes(data))


def _write_yaml(path: Path, image: Path, grid: GridSpec, mode: str,
                thresholds: tuple[float, float]) -> None:
    x0, y0 = grid.origin_xy
    text = (f"image: {image.name}\nmode: {mode}\nresolution: {grid.resolution}\n"
                    f"origin: [{x0}, {y0}, 0.0]\nnegate: 0\n"
                    f"occupied_thresh: {thresholds[0]}\nfree_thresh: {thresholds[1]}\n")
    write_atomically(path, lambda tmp: tmp.write_text(text))


def cost_to_pixels(cost: np.ndarray, occupancy: np.ndarray) -> np.ndarray:
    """One cost layer (H, W), C in 0..1, as map_server ``scale`` pixels: 255·(1 − C) rounded,
    0 (lethal) where occupied, unobserved or C is not finite."""
    c = np.clip(np.nan_to_num(cost, nan=1.0), 0.0, 1.0)
    pixels = np.rint(255.0 * (1.0 - c)).astype(np.uint8)
    pixels[occupancy != FREE] = 0
    return pixels


def occupancy_to_pixels(occupancy: np.ndarray) -> np.ndarray:
    """The occupancy (H, W) as map_server ``trinary`` pixels: free 254, occupied 0, unknown 205."""
    pixels = np.full(occupancy.shape, TRINARY_UNKNOWN, np.uint8)
    pixels[occupancy == FREE] = TRINARY_FREE
    pixels[occupancy == OCCUPIED] = TRINARY_OCCUPIED
    return pixels


def write_nav2(path: str | Path, cost: np.ndarray, occupancy: np.ndarray,
               grid: GridSpec) -> list[Path]:
    """map_server image + YAML pairs: ``<stem>_heading<k>.pgm/.yaml`` for each heading θ_k
    (``<stem>_cost`` for an isotropic costmap's one layer) and ``<stem>_occupancy.pgm/.yaml``,
    beside ``path`` (its suffix is dropped), or inside ``path`` when it is a directory (or
    ends in ``/``): ``path/costmap_heading<k>.pgm`` … Each file is written atomically, and
    the whole set under one lock (``<stem>.nav2.lock``): two writers of one set take turns.
    Returns the YAML files, headings first."""
    _check(cost, occupancy, grid)
    stem = nav2_stem(path)
    with build_lock(stem.with_name(stem.name + ".nav2"), hidden=True):
        return _write_nav2_files(stem, cost, occupancy, grid)


def nav2_stem(path: str | Path, name: str = "costmap") -> Path:
    """Where :func:`write_nav2` puts its files: ``path`` without its suffix, or
    ``path/<name>`` when ``path`` is a directory or ends in a path separator."""
    text = str(path)
    if text.endswith(("/", os.sep)) or Path(text).is_dir():
        return Path(text) / name
    p = Path(text)
    return p.parent / p.stem


def _write_nav2_files(stem: Path, cost: np.ndarray, occupancy: np.ndarray,
                      grid: GridSpec) -> list[Path]:
    """:func:`write_nav2`'s files at ``stem`` (its lock held)."""
    written = []
    k_layers = cost.shape[0]
    layers = [(f"heading{k}" if k_layers > 1 else "cost", cost_to_pixels(cost[k], occupancy),
               "scale", SCALE_THRESHOLDS) for k in range(k_layers)]
    layers.append(("occupancy", occupancy_to_pixels(occupancy), "trinary", TRINARY_THRESHOLDS))
    for label, pixels, mode, thresholds in layers:
        pgm = Path(f"{stem}_{label}.pgm")
        _write_pgm(pgm, pixels[::-1])
        yaml = pgm.with_suffix(".yaml")
        _write_yaml(yaml, pgm, grid, mode, thresholds)
        written.append(yaml)
    return written
