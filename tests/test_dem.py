"""Real terrain in: GeoTIFF and ESRI ASCII DEMs, projected and geographic, with no-data."""

import sys

import numpy as np
import pytest

from dgt_lib.app.cli import main
from dgt_lib.app.plan_one import crs_to_local, load_world
from dgt_lib.core.config import get_profile
from dgt_lib.world.dem import (
    import_rasterio,
    largest_valid_rectangle,
    load_dem,
    read_dem,
    utm_epsg,
)
from dgt_lib.world.worlds import HeightmapError

rasterio = pytest.importorskip("rasterio")
from rasterio.transform import Affine  # noqa: E402


def from_origin(west: float, north: float, xsize: float, ysize: float) -> Affine:
    """A north-up transform (rasterio's ``from_origin``, without its deprecated ``*``)."""
    return Affine(xsize, 0.0, west, 0.0, -ysize, north)

N = 60
"""DEM side [cells]."""


def plane(n: int = N) -> np.ndarray:
    """Heights of a tilted plane, north-up rows (row 0 the north edge): 100 m at the
    north-west corner, +0.1 m per column (east), -0.5 m per row (south)."""
    r, c = np.mgrid[0:n, 0:n]
    return (100.0 - 0.5 * r + 0.1 * c).astype(np.float32)


def write_dem(path, heights, *, crs, transform, nodata=-9999.0, driver="GTiff"):
    with rasterio.open(path, "w", driver=driver, height=heights.shape[0],
                       width=heights.shape[1], count=1, dtype="float32", crs=crs,
                       transform=transform, nodata=nodata) as dst:
        dst.write(heights, 1)
    return path


def utm_dem(tmp_path, heights=None, name="utm.tif"):
    """A 60 m × 60 m DEM at 1 m in UTM 31N, its north-west corner at (500000, 5000060)."""
    return write_dem(tmp_path / name, plane() if heights is None else heights,
                     crs="EPSG:32631", transform=from_origin(500000.0, 5000060.0, 1.0, 1.0))


def geo_dem(tmp_path, heights=None, name="geo.tif"):
    """A DEM in degrees (EPSG:4326) near (2.0003° E, 45.0003° N): 60 × 60 cells of 1e-5°."""
    return write_dem(tmp_path / name, plane() if heights is None else heights,
                     crs="EPSG:4326", transform=from_origin(2.0, 45.0006, 1e-5, 1e-5))


def test_projected_dem_keeps_its_crs_and_is_resampled_south_row_first(tmp_path):
    dem = read_dem(utm_dem(tmp_path), 0.4)
    assert dem.heights.shape == (150, 150) and dem.resolution == 0.4
    assert dem.georef.origin == (500000.0, 5000000.0)  # the south-west corner
    assert rasterio.crs.CRS.from_wkt(dem.georef.crs).to_epsg() == 32631
    # row 0 is the south edge now: it is 29.5 m lower than the north edge's
    assert dem.heights[0].mean() < dem.heights[-1].mean() - 29.0
    # a cell centre inside: x = 30.2 m, y = 30.2 m from the south-west corner
    row, col = 75, 75
    expected = 100.0 - 0.5 * (N - 30.2 - 0.5) + 0.1 * (30.2 - 0.5)
    assert dem.heights[row, col] == pytest.approx(expected, abs=1e-3)


def test_geographic_dem_is_reprojected_to_the_utm_zone_of_its_centre(tmp_path):
    dem = read_dem(geo_dem(tmp_path), 0.4)
    assert rasterio.crs.CRS.from_wkt(dem.georef.crs).to_epsg() == 32631
    h, w = dem.heights.shape
    # 60 × 1e-5° ≈ 66.7 m north-south and 47.2 m east-west at 45° N
    assert 62.0 < h * 0.4 < 67.0 and 43.0 < w * 0.4 < 48.0
    assert np.isfinite(dem.heights).all()
    assert 70.0 <= dem.heights.min() and dem.heights.max() <= 106.0  # no invented zero
    # the DEM's centre in degrees lies at the map's centre in metres
    x, y = dem.georef.to_local(2.0003, 45.0003)
    assert x[0] == pytest.approx(w * 0.4 / 2, abs=1.5)
    assert y[0] == pytest.approx(h * 0.4 / 2, abs=1.5)


def test_nodata_is_an_error_naming_the_count_and_the_way_out(tmp_path):
    heights = plane()
    heights[10:14, 20:25] = -9999.0
    with pytest.raises(HeightmapError, match=r"20 no-data cells of 3600.*--nodata crop"):
        read_dem(utm_dem(tmp_path, heights), 0.4)


@pytest.mark.parametrize("make", [utm_dem, geo_dem])
def test_nodata_crop_keeps_the_largest_valid_rectangle_never_a_zero(tmp_path, make):
    heights = plane()
    heights[:, :12] = -9999.0  # a void along the west edge
    heights[50:, :] = -9999.0  # and along the south edge
    dem = read_dem(make(tmp_path, heights), 0.4, nodata="crop")
    assert np.isfinite(dem.heights).all()
    assert dem.heights.min() > 70.0  # neither the no-data value nor 0 got in
    full = read_dem(make(tmp_path, plane(), name="full.tif"), 0.4)
    assert dem.heights.size < 0.75 * full.heights.size  # the voids are gone...
    assert dem.heights.size > 0.55 * full.heights.size  # ...and little else
    # the crop is in place: the same ground has the same coordinates in both
    ex, ey = np.subtract(dem.georef.origin, full.georef.origin)
    assert ex > 4.0 and ey > 3.0  # the west and south voids moved the corner north-east
    r, c = round(ey / 0.4), round(ex / 0.4)
    np.testing.assert_allclose(dem.heights[5:10, 5:10], full.heights[r + 5:r + 10, c + 5:c + 10],
                               atol=0.05)


def test_a_dem_too_large_to_map_is_an_error_before_resampling(tmp_path):
    big = write_dem(tmp_path / "big.tif", plane(), crs="EPSG:32631",
                    transform=from_origin(500000.0, 5006000.0, 100.0, 100.0))  # 6 km square
    with pytest.raises(HeightmapError, match=r"6000 m × 6000 m.*crop it"):
        read_dem(big, 0.4)


def test_esri_ascii_grid_without_a_crs_uses_its_own_units(tmp_path):
    path = write_dem(tmp_path / "dem.asc", plane(), crs=None,
                     transform=from_origin(1000.0, 2060.0, 1.0, 1.0), driver="AAIGrid")
    dem = read_dem(path, 0.5)
    assert dem.heights.shape == (120, 120)
    assert dem.georef.crs is None and dem.georef.origin == (1000.0, 2000.0)
    # cell (10, 10) is centred 5.25 m east and north of the south-west corner
    assert dem.heights[10, 10] == pytest.approx(100.0 - 0.5 * (N - 5.25 - 0.5) + 0.1 * 4.75,
                                                abs=1e-3)


def test_esri_ascii_grid_with_nodata_is_an_error(tmp_path):
    heights = plane()
    heights[0, 0] = -9999.0
    path = write_dem(tmp_path / "dem.asc", heights, crs="EPSG:32631",
                     transform=from_origin(0.0, 60.0, 1.0, 1.0), driver="AAIGrid")
    with pytest.raises(HeightmapError, match="1 no-data cells"):
        read_dem(path, 0.4)


def test_a_dem_becomes_a_world_at_the_profiles_heightfield_resolution(tmp_path):
    profile = get_profile("smoke")
    world, georef = load_world(str(utm_dem(tmp_path)), profile)
    assert world.name == "utm" and world.resolution == profile.worlds.hfield_resolution_m
    assert world.grid.origin_xy == (0.0, 0.0) and georef.origin == (500000.0, 5000000.0)
    direct, _ = load_dem(utm_dem(tmp_path), profile.worlds.hfield_resolution_m)
    np.testing.assert_array_equal(world.heights, direct.heights)
    # --crs-coords: a start and goal in the file's CRS → metres from the south-west corner
    start, goal = crs_to_local(georef, (500010.0, 5000020.0, 0.5), (500040.0, 5000030.0))
    assert start == pytest.approx((10.0, 20.0, 0.5)) and goal == pytest.approx((40.0, 30.0))
    with pytest.raises(ValueError, match="need a DEM"):
        crs_to_local(None, start, goal)


def test_missing_rasterio_is_a_one_line_error_naming_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "rasterio", None)
    with pytest.raises(HeightmapError, match=r"pip install 'dgt-kit\[geo\]'"):
        import_rasterio()


def test_largest_valid_rectangle_matches_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(20):
        valid = rng.random((7, 9)) < 0.8
        rows, cols = largest_valid_rectangle(valid)
        assert valid[rows, cols].all()
        best = max(((r1 - r0) * (c1 - c0)) for r0 in range(7) for r1 in range(r0 + 1, 8)
                   for c0 in range(9) for c1 in range(c0 + 1, 10)
                   if valid[r0:r1, c0:c1].all()) if valid.any() else 0
        assert (rows.stop - rows.start) * (cols.stop - cols.start) == best


@pytest.mark.parametrize("lon,lat,epsg", [(2.0, 45.0, 32631), (-70.6, -33.4, 32719),
                                          (179.9, 10.0, 32660), (-180.0, 0.0, 32601)])
def test_utm_zone_of_a_point(lon, lat, epsg):
    assert utm_epsg(lon, lat) == epsg


def test_crs_coords_on_a_plain_heightmap_is_a_usage_error(tmp_path, capsys):
    np.save(tmp_path / "flat.npy", np.zeros((40, 40), np.float32))
    assert main(["plan", "--world", str(tmp_path / "flat.npy"), "--vehicle", "jeep", "--start",
                 "1,2,0", "--goal", "3,4", "--crs-coords", "--profile", "smoke"]) == 2
    assert "coordinates in the file's CRS need a DEM" in capsys.readouterr().err


ASC_HEADER = "ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize {cell}\n"


def _asc(tmp_path, rows: str, cell: str = "1", name: str = "g.asc"):
    path = tmp_path / name
    path.write_text(ASC_HEADER.format(cell=cell) + rows)
    return path


def test_a_malformed_asc_number_is_an_error_naming_the_file_and_line(tmp_path):
    path = _asc(tmp_path, "1 2 3 4\n5 2x 7 8\n9 10 11 12\n")  # GDAL read 2x as 2, abc as 0
    with pytest.raises(HeightmapError, match=r"g\.asc line 7: '2x' is not a number"):
        read_dem(path, 0.5)
    with pytest.raises(HeightmapError, match="holds 11 numbers; its header declares 3 × 4"):
        read_dem(_asc(tmp_path, "1 2 3 4\n5 6 7 8\n9 10 11\n"), 0.5)


def test_an_asc_with_cellsize_0_or_a_huge_declared_size_is_one_line_before_reading(tmp_path):
    with pytest.raises(HeightmapError, match="cellsize 0 must be a finite number > 0"):
        read_dem(_asc(tmp_path, "1 2 3 4\n5 6 7 8\n9 10 11 12\n", cell="0"), 0.5)
    huge = tmp_path / "huge.asc"
    huge.write_text("ncols 100000\nnrows 100000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n")
    with pytest.raises(HeightmapError, match="declares 100000 × 100000 cells"):
        read_dem(huge, 0.5)


def test_a_dem_file_too_large_is_refused_from_its_header_before_any_cell_is_read(
        tmp_path, monkeypatch):
    from dgt_lib.world import dem

    path = utm_dem(tmp_path)
    monkeypatch.setattr(dem, "MAX_SOURCE_CELLS", N * N - 1)

    def no_read(*args, **kwargs):
        raise AssertionError("cells read before the size check")

    monkeypatch.setattr(rasterio.io.DatasetReader, "read", no_read)
    with pytest.raises(HeightmapError, match="crop or coarsen it first"):
        read_dem(path, 1.0)


def test_a_truncated_geotiff_is_one_line(tmp_path):
    path = utm_dem(tmp_path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(HeightmapError, match=r"cannot read .*utm\.tif as a DEM") as err:
        read_dem(path, 1.0)
    assert "\n" not in str(err.value)


def test_a_multi_band_dem_says_which_band_it_read_and_band_selects_another(tmp_path):
    path = tmp_path / "two.tif"
    with rasterio.open(path, "w", driver="GTiff", height=N, width=N, count=2, dtype="float32",
                       crs="EPSG:32631",
                       transform=from_origin(500000.0, 5000060.0, 1.0, 1.0)) as dst:
        dst.write(plane(), 1)
        dst.write(plane() + 1000.0, 2)
    said = []
    first = read_dem(path, 1.0, log=said.append)
    assert len(said) == 1 and "has 2 bands: reading heights from band 1" in said[0]
    second = read_dem(path, 1.0, band=2, log=said.append)
    assert len(said) == 1  # asked for: nothing to say
    assert np.allclose(second.heights, first.heights + 1000.0)
    with pytest.raises(HeightmapError, match="--band 3 is not one of them"):
        read_dem(path, 1.0, band=3)


def test_crs_coords_beyond_the_pole_are_one_line(tmp_path):
    world, georef = load_dem(geo_dem(tmp_path), 0.4)
    with pytest.raises(ValueError, match=r"\(2, 95\).*beyond ±90°|\(2, 95\).*cannot be conv"):
        crs_to_local(georef, (2.0, 95.0, 0.0), (2.0002, 45.0002))


def test_a_dem_coarser_than_a_vehicle_says_so_once_and_a_fine_one_says_nothing(tmp_path):
    said = []
    read_dem(utm_dem(tmp_path), 0.4, log=said.append)  # 1 m cells: fine
    assert said == []
    coarse = write_dem(tmp_path / "coarse.tif", plane(), crs="EPSG:32631",
                       transform=from_origin(500000.0, 5001800.0, 30.0, 30.0))
    read_dem(coarse, 5.0, log=said.append)
    assert len(said) == 1 and "cells are 30 m across, coarser than a vehicle" in said[0]
    assert "planar facets 30 m wide" in said[0]
    said.clear()
    degrees = write_dem(tmp_path / "srtm.tif", plane(), crs="EPSG:4326",
                        transform=from_origin(2.0, 45.05, 1 / 1200, 1 / 1200))  # 3 arc-seconds
    read_dem(degrees, 5.0, log=said.append)
    assert len(said) == 1 and "coarser than a vehicle" in said[0]
