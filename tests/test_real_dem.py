"""A real DEM in and its costmap out: matplotlib's Jacksboro SRTM sample through
examples/real_dem.py, `dgt_lib.world.dem` and `dgt costmap`."""

from pathlib import Path

import numpy as np
import pytest

from dgt_lib.app.cli import main
from dgt_lib.core.config import get_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.mapping.occupancy import FREE
from dgt_lib.world.dem import read_dem
from examples.real_dem import (
    WINDOW_CELLS,
    choose_window,
    load_sample,
    window_queries,
    write_window,
)

rasterio = pytest.importorskip("rasterio")
from rasterio.warp import transform_bounds  # noqa: E402

PROFILE = get_profile("smoke")


@pytest.fixture(scope="module")
def sample():
    dem = load_sample()
    window = choose_window(dem)
    return dem, (window.row, window.col), window


def test_the_sample_is_the_documented_grid(sample):
    dem, *_ = sample
    assert dem.heights.shape == (344, 403)
    assert dem.step == pytest.approx(1 / 1200)  # 3 arc-seconds
    assert (dem.west, dem.north) == pytest.approx((-84.41375, 36.73291667))
    dx, dy = dem.cell_size_m()
    assert 74.0 < dx < 75.0 and 92.0 < dy < 93.0


def test_the_window_is_a_geographic_geotiff_of_the_samples_cells(sample, tmp_path):
    dem, (row, col), _ = sample
    path = write_window(tmp_path / "jacksboro.tif", dem, row, col)
    with rasterio.open(path) as src:
        assert src.crs.to_epsg() == 4326 and src.shape == (WINDOW_CELLS, WINDOW_CELLS)
        assert src.nodata is None
        west, north = src.transform @ (0, 0)
        assert (west, north) == pytest.approx((dem.west + col * dem.step,
                                               dem.north - row * dem.step))
        assert src.res == pytest.approx((dem.step, dem.step))
        np.testing.assert_array_equal(src.read(1),
                                      dem.heights[row:row + WINDOW_CELLS, col:col + WINDOW_CELLS])


def test_the_window_becomes_a_metric_world_of_its_size_and_heights(sample, tmp_path):
    dem, (row, col), _ = sample
    path = write_window(tmp_path / "jacksboro.tif", dem, row, col)
    res = PROFILE.worlds.hfield_resolution_m
    world = read_dem(path, res)
    assert rasterio.crs.CRS.from_wkt(world.georef.crs).to_epsg() == 32616  # UTM 16N
    dx, dy = dem.cell_size_m()
    h, w = world.heights.shape
    # the rotation into UTM crops the corners it leaves empty: a few % of each side
    assert 0.95 * WINDOW_CELLS * dx < w * res <= WINDOW_CELLS * dx * 1.001
    assert 0.95 * WINDOW_CELLS * dy < h * res <= WINDOW_CELLS * dy * 1.001
    source = dem.heights[row:row + WINDOW_CELLS, col:col + WINDOW_CELLS]
    assert np.isfinite(world.heights).all()
    assert world.heights.min() >= source.min() - 1e-3  # bilinear: no invented heights
    assert world.heights.max() <= source.max() + 1e-3
    assert np.ptp(world.heights) > 0.95 * np.ptp(source)


def test_the_window_has_a_climbable_route_beside_a_slope_carla_cola_only_descends(
        sample, tmp_path):
    """What the window was chosen for survives the resampling to the kit's 0.4 m grid:
    its two query points are joined by ground gentler than carla_cola's climb, the
    straight line between them crosses ground steeper than it, and the way up rises."""
    from scipy.ndimage import label

    dem, (row, col), window = sample
    res = PROFILE.worlds.hfield_resolution_m
    world = read_dem(write_window(tmp_path / "jacksboro.tif", dem, row, col), res)
    up, down = window_queries(dem, window, world.georef)
    (sx, sy, yaw), (gx, gy) = up
    assert down == ((gx, gy, pytest.approx(yaw - np.pi if yaw > 0 else yaw + np.pi, abs=1e-3)),
                    (sx, sy))
    assert np.hypot(gx - sx, gy - sy) > 100.0  # whole facets apart
    assert np.cos(yaw) * (gx - sx) + np.sin(yaw) * (gy - sy) > 0.99 * np.hypot(gx - sx, gy - sy)

    def cell(x, y):
        return int(y / res), int(x / res)

    heights = world.heights.astype(float)
    rise = heights[cell(gx, gy)] - heights[cell(sx, sy)]
    assert rise == pytest.approx(window.rise_m, abs=3.0) and rise > 10.0
    slope = np.degrees(np.arctan(np.hypot(*np.gradient(heights, res))))
    climb = get_vehicle("carla_cola").max_climb_deg
    regions, _ = label(slope < climb)
    assert regions[cell(sx, sy)] != 0 and regions[cell(sx, sy)] == regions[cell(gx, gy)]
    t = np.linspace(0.0, 1.0, 400)
    line = slope[((sy + t * (gy - sy)) / res).astype(int),
                 ((sx + t * (gx - sx)) / res).astype(int)]
    assert (line > climb).mean() > 0.1  # its straight line climbs what carla_cola cannot


@pytest.mark.filterwarnings("ignore:.*near-constant")  # a model of 2 epochs learns little
def test_dgt_costmap_on_the_window_writes_k_headings_in_utm(sample, synthetic_pipeline,
                                                             capsys):
    """End to end on the smoke profile with a model trained on a synthetic dataset (no
    driving episodes: seconds), on the 2 × 2 cells at the middle of the window (its survey takes a
    sixth of the whole window's)."""
    dem, (row, col), _ = sample
    tmp_path = synthetic_pipeline
    path = write_window(tmp_path / "corner.tif", dem, row + 2, col + 2, cells=2)
    out = tmp_path / "cola.tif"
    assert main(["costmap", "--world", str(path), "--vehicle", "carla_cola", "--profile",
                 "smoke", "--out", str(out)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == str(out)  # after the training notice
    world = read_dem(path, PROFILE.worlds.hfield_resolution_m)
    k = PROFILE.costmap.n_headings
    with rasterio.open(out) as src:
        assert src.count == k + 1 and src.crs.to_epsg() == 32616  # the world's CRS
        assert src.shape == world.heights.shape and src.res == pytest.approx((0.4, 0.4))
        assert (src.bounds.left, src.bounds.bottom) == pytest.approx(world.georef.origin)
        assert src.descriptions[k // 4] == f"heading_k={k // 4} theta_deg=90.0"
        bands = src.read()
        lonlat = transform_bounds(src.crs, "EPSG:4326", *src.bounds)
    with rasterio.open(path) as dem_file:
        window = dem_file.bounds
    # back in degrees, the costmap lies inside the DEM's window (to within one of its
    # 0.4 m cells: reprojection keeps a cell whose centre is inside) and covers most of it
    dx, dy = dem.cell_size_m()
    tol_lon, tol_lat = 0.4 / dx * dem.step, 0.4 / dy * dem.step
    assert window.left - tol_lon <= lonlat[0] and lonlat[2] <= window.right + tol_lon
    assert window.bottom - tol_lat <= lonlat[1] and lonlat[3] <= window.top + tol_lat
    assert (lonlat[2] - lonlat[0]) * (lonlat[3] - lonlat[1]) > 0.9 * (
        (window.right - window.left) * (window.top - window.bottom))
    free = bands[k] == FREE
    assert free.mean() > 0.5
    assert ((bands[:k, free] >= 0.0) & (bands[:k, free] <= 1.0)).all()


def test_the_documented_commands_plan_the_scripts_queries(sample, tmp_path):
    """README and docs/usage.md quote the queries `examples/real_dem.py` prints."""
    import re

    dem, (row, col), window = sample
    world = read_dem(write_window(tmp_path / "jacksboro.tif", dem, row, col),
                     PROFILE.worlds.hfield_resolution_m)
    expected = {(f"{x:g},{y:g},{yaw:g}", f"{gx:g},{gy:g}")
                for (x, y, yaw), (gx, gy) in window_queries(dem, window, world.georef)}
    root = Path(__file__).resolve().parent.parent
    for page in ("README.md", "docs/usage.md"):
        text = " ".join((root / page).read_text().replace("\\\n", " ").split())
        found = set(re.findall(r"jacksboro\.tif --vehicle carla_cola --start (\S+) --goal (\S+)",
                               text))
        assert found >= expected, page
