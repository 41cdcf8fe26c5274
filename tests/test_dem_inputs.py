"""What a DEM's costmap reads: its geometry alone (no invented colour), or the colours of an
orthophoto given with --image."""

import json

import numpy as np
import pytest

from dgt_lib.app.cli import main
from dgt_lib.app.plan_one import load_world
from dgt_lib.core.config import get_profile
from dgt_lib.stages.costmaps import world_bev
from dgt_lib.stages.paths import data_dir
from dgt_lib.world import worlds

rasterio = pytest.importorskip("rasterio")
from rasterio.transform import Affine  # noqa: E402

PROFILE = get_profile("smoke")
WEST, NORTH = 500000.0, 5000030.0
"""The DEM's north-west corner in UTM 31N [m]: 40 m × 30 m at 1 m."""
RED, BLUE = (200, 40, 30), (30, 60, 190)
"""The test orthophoto's west and east halves, 8-bit RGB."""


def write_dem(path):
    """A flat 40 m × 30 m DEM at 250 m with a 3 m block (steep faces: painted as rock)."""
    heights = np.full((30, 40), 250.0, np.float32)
    heights[10:20, 18:24] = 253.0
    with rasterio.open(path, "w", driver="GTiff", height=30, width=40, count=1,
                       dtype="float32", crs="EPSG:32631",
                       transform=Affine(1.0, 0.0, WEST, 0.0, -1.0, NORTH)) as dst:
        dst.write(heights, 1)
    return path


def write_ortho(path, *, cell=0.5, west=WEST, bands=3, dtype="uint8"):
    """An orthophoto over the DEM at ``cell`` [m]: its west half RED, its east half BLUE."""
    h, w = int(30 / cell), int(40 / cell)
    rgb = np.empty((bands, h, w), dtype)
    for b in range(bands):
        rgb[b, :, : w // 2], rgb[b, :, w // 2:] = RED[b % 3], BLUE[b % 3]
    with rasterio.open(path, "w", driver="GTiff", height=h, width=w, count=bands, dtype=dtype,
                       crs="EPSG:32631",
                       transform=Affine(cell, 0.0, west, 0.0, -cell, NORTH)) as dst:
        dst.write(rgb)
    return path


@pytest.fixture
def quick(synthetic_pipeline):
    """A private data directory and a synthetic dataset (no driving episodes: seconds)."""
    return synthetic_pipeline


def costmap(dem, out, *extra):
    assert main(["costmap", "--world", str(dem), "--vehicle", "jeep", "--profile", "smoke",
                 "--out", str(out), *extra]) == 0
    with rasterio.open(out) as src:
        return src.read()


@pytest.mark.filterwarnings("ignore:.*near-constant")  # a model of 2 epochs learns little
def test_a_dem_without_imagery_is_mapped_by_the_geometry_model_and_no_painted_colour(
        quick, monkeypatch, capsys):
    dem = write_dem(quick / "dem.tif")
    first = costmap(dem, quick / "a.tif")
    assert "costmap input: geometry only (no imagery)" in capsys.readouterr().err
    models = data_dir(PROFILE) / "models"
    assert (models / "multitask_geometry.pt").exists()
    assert not (models / "multitask.pt").exists()  # the RGB-D model was neither used nor built
    world, _ = load_world(str(dem), PROFILE)
    assert np.ptp(world.colors) == 0.0  # one colour: no rock painted on the block's faces
    # whatever the slope colouring paints, the costmap stays the same
    monkeypatch.setattr(worlds, "_colorize",
                        lambda h, *a, **k: np.tile(np.float32([1.0, 0.0, 1.0]), (*h.shape, 1)))
    np.testing.assert_array_equal(costmap(dem, quick / "b.tif"), first)
    capsys.readouterr()
    assert main(["plan", "--world", str(dem), "--vehicle", "jeep", "--profile", "smoke",
                 "--start", "5,5,0", "--goal", "35,25", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["input"] == "geometry only (no imagery)"


@pytest.mark.filterwarnings("ignore:.*near-constant")
def test_a_height_map_file_is_grey_and_mapped_by_the_geometry_model(quick, capsys):
    """A .npy height map has no imagery either: no rock painted on its steep faces, and
    the geometry-only model maps it."""
    heights = np.zeros((75, 100))
    heights[25:50, 45:60] = 3.0  # a 3 m block: steep faces
    np.save(quick / "block.npy", heights)
    world, _ = load_world(str(quick / "block.npy"), PROFILE)
    assert np.ptp(world.colors) == 0.0
    assert main(["plan", "--world", str(quick / "block.npy"), "--vehicle", "jeep",
                 "--profile", "smoke", "--start", "5,5,0", "--goal", "35,25", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["input"] == "geometry only (no imagery)"
    models = data_dir(PROFILE) / "models"
    assert (models / "multitask_geometry.pt").exists() and not (models / "multitask.pt").exists()


@pytest.mark.filterwarnings("ignore:.*near-constant")
def test_image_becomes_the_maps_colour_and_the_rgbd_model_reads_it(quick, capsys):
    dem, ortho = write_dem(quick / "dem.tif"), write_ortho(quick / "ortho.tif")
    costmap(dem, quick / "c.tif", "--image", str(ortho))
    assert "costmap input: RGB-D with imagery from ortho.tif" in capsys.readouterr().err
    assert (data_dir(PROFILE) / "models" / "multitask.pt").exists()
    assert not (data_dir(PROFILE) / "models" / "multitask_geometry.pt").exists()
    world, _ = load_world(str(dem), PROFILE, image=ortho)
    bev, _ = world_bev(world, PROFILE, progress=False)  # the one the costmap was built on
    rows, cols = bev.grid.xy_to_cell(np.array([5.0, 35.0]), np.array([25.0, 5.0]))
    for r, c, colour in zip(rows, cols, (RED, BLUE), strict=True):  # flat ground: exact
        np.testing.assert_allclose(bev.rgb[r, c], np.array(colour) / 255.0, atol=0.02)
    assert main(["plan", "--world", str(dem), "--vehicle", "jeep", "--profile", "smoke",
                 "--start", "5,5,0", "--goal", "35,25", "--image", str(ortho), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["input"] == "RGB-D with imagery from ortho.tif"


@pytest.mark.parametrize("make, message", [
    (lambda p: write_ortho(p, bands=4), "has 4 band(s) of uint8: --image needs 3 bands"),
    (lambda p: write_ortho(p, dtype="uint16"), "needs 3 bands of 8-bit RGB"),
    (lambda p: write_ortho(p, west=WEST + 1000.0), "does not overlap the DEM"),
    (lambda p: write_ortho(p, west=WEST + 20.0), "covers only 50 % of the DEM"),
    (lambda p: p.write_text("not a GeoTIFF") and p, "cannot read"),
])
@pytest.mark.parametrize("command", ["costmap", "plan"])
def test_a_bad_image_is_exit_2_with_one_line_naming_it(quick, capsys, make, message, command):
    dem, ortho = write_dem(quick / "dem.tif"), quick / "ortho.tif"
    make(ortho)
    args = ["--out", str(quick / "x.tif")] if command == "costmap" else [
        "--start", "5,5,0", "--goal", "35,25"]
    assert main([command, "--world", str(dem), "--vehicle", "jeep", "--profile", "smoke",
                 "--image", str(ortho), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(ortho) in err and message in err
    assert not (data_dir(PROFILE) / "models").exists()  # refused before any work


def test_image_on_a_world_that_is_not_a_dem_is_exit_2(quick, capsys):
    ortho = write_ortho(quick / "ortho.tif")
    assert main(["costmap", "--world", "hill", "--vehicle", "jeep", "--profile", "smoke",
                 "--out", str(quick / "x.tif"), "--image", str(ortho)]) == 2
    assert "--image colours a DEM world" in capsys.readouterr().err
