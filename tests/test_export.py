"""Costmaps out: GeoTIFF bands per heading and Nav2 map_server images, read back."""

import json
import sys

import numpy as np
import pytest

from dgt_lib.app.cli import main
from dgt_lib.core import artifacts
from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.export import write_geotiff, write_nav2
from dgt_lib.mapping.occupancy import FREE, OCCUPIED, UNOBSERVED
from dgt_lib.world.dem import Georeference

rasterio = pytest.importorskip("rasterio")
from rasterio.transform import Affine  # noqa: E402


def from_origin(west: float, north: float, xsize: float, ysize: float) -> Affine:
    """A north-up transform (rasterio's ``from_origin``, without its deprecated ``*``)."""
    return Affine(xsize, 0.0, west, 0.0, -ysize, north)

K, H, W = 8, 12, 20
GRID = GridSpec((0.0, 0.0), 0.4, (H, W))
UTM = rasterio.crs.CRS.from_epsg(32631).to_wkt()


def synthetic() -> tuple[np.ndarray, np.ndarray]:
    """A (K, H, W) cost C = (k + row / H) / K in 0..1 (distinct per heading and row, rising
    to the north) and an occupancy with an occupied and an unobserved block."""
    k, r, _ = np.meshgrid(np.arange(K), np.arange(H), np.arange(W), indexing="ij")
    cost = ((k + r / H) / K).astype(np.float32)
    occ = np.full((H, W), FREE, np.uint8)
    occ[2:4, 3:6] = OCCUPIED
    occ[9:, 15:] = UNOBSERVED
    return cost, occ


def test_geotiff_bands_are_the_headings_then_the_occupancy_in_the_dems_crs(tmp_path):
    cost, occ = synthetic()
    georef = Georeference(UTM, (500000.0, 5000000.0), UTM)
    path = write_geotiff(tmp_path / "c.tif", cost, occ, GRID, georef)
    with rasterio.open(path) as src:
        assert src.count == K + 1 and src.crs.to_epsg() == 32631
        assert src.bounds == pytest.approx((500000.0, 5000000.0, 500008.0, 5000004.8))
        bands = src.read()
        descriptions = src.descriptions
        tags = [src.tags(b + 1) for b in range(K + 1)]
    np.testing.assert_array_equal(bands[:K], cost[:, ::-1])  # north row first
    np.testing.assert_array_equal(bands[K], occ[::-1])
    assert descriptions[2] == "heading_k=2 theta_deg=90.0"
    assert descriptions[K].startswith("occupancy")
    assert [t.get("theta_deg") for t in tags[:K]] == [f"{45.0 * k:.1f}" for k in range(K)]
    # a point in the world frame lands in the same cell through the file's transform
    x, y = 5.0, 1.0  # → row 2 (from the south), column 12
    with rasterio.open(path) as src:
        row, col = src.index(500000.0 + x, 5000000.0 + y)
    assert bands[3, row, col] == cost[3, 2, 12]


def test_geotiff_of_a_world_without_a_crs_is_in_its_metric_frame(tmp_path):
    cost, occ = synthetic()
    grid = GridSpec((-4.0, 2.0), 0.4, (H, W))
    with rasterio.open(write_geotiff(tmp_path / "c.tif", cost, occ, grid)) as src:
        assert src.crs is None
        assert src.bounds == pytest.approx((-4.0, 2.0, 4.0, 6.8))


def _yaml(path) -> dict[str, str]:
    return dict(line.split(": ", 1) for line in path.read_text().splitlines())


def _pgm(path) -> np.ndarray:
    data = path.read_bytes()
    magic, size, maxval, pixels = data.split(b"\n", 3)
    w, h = (int(v) for v in size.split())
    assert magic == b"P5" and maxval == b"255"
    return np.frombuffer(pixels, np.uint8).reshape(h, w)


def _map_server_occ(pixels: np.ndarray) -> np.ndarray:
    """map_server's occupancy probability of a pixel with negate: 0."""
    return (255.0 - pixels) / 255.0


def test_nav2_yaml_has_map_servers_fields_and_the_pgm_reads_back(tmp_path):
    cost, occ = synthetic()
    grid = GridSpec((-4.0, 2.0), 0.4, (H, W))
    yamls = write_nav2(tmp_path / "jeep.yaml", cost, occ, grid)
    assert [p.name for p in yamls] == [*(f"jeep_heading{k}.yaml" for k in range(K)),
                                       "jeep_occupancy.yaml"]
    for k in range(K):
        fields = _yaml(yamls[k])
        assert fields["image"] == f"jeep_heading{k}.pgm" and fields["mode"] == "scale"
        assert float(fields["resolution"]) == 0.4 and fields["negate"] == "0"
        assert fields["origin"] == "[-4.0, 2.0, 0.0]"
        occupied_t, free_t = float(fields["occupied_thresh"]), float(fields["free_thresh"])
        p = _pgm(tmp_path / fields["image"])[::-1]  # back to south row first
        assert p.shape == (H, W)
        prob = _map_server_occ(p)
        free = occ == FREE
        np.testing.assert_allclose(prob[free], cost[k][free], atol=0.5 / 255)  # C, as scaled
        assert (prob[~free] > occupied_t).all()  # occupied and unobserved are lethal
        assert (prob[free] < occupied_t).all()
        assert free_t < 1.0 / 255 and (prob[free & (cost[k] == 0)] < free_t).all()
    fields = _yaml(yamls[-1])
    assert fields["mode"] == "trinary"
    prob = _map_server_occ(_pgm(tmp_path / fields["image"])[::-1])
    occupied_t, free_t = float(fields["occupied_thresh"]), float(fields["free_thresh"])
    state = np.where(prob > occupied_t, OCCUPIED, np.where(prob < free_t, FREE, UNOBSERVED))
    np.testing.assert_array_equal(state, occ)  # map_server recovers free/occupied/unknown


def test_writers_reject_a_costmap_off_the_grid(tmp_path):
    cost, occ = synthetic()
    with pytest.raises(ValueError, match="on the grid"):
        write_nav2(tmp_path / "x", cost[:, :-1], occ, GRID)


def test_dgt_costmap_on_a_tiny_dem(tmp_path, monkeypatch, capsys):
    """End to end on the smoke profile: a 40 m × 30 m DEM with a block, the binary method:
    dgt costmap in both formats, then dgt plan on it with --crs-coords."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    heights = np.full((30, 40), 250.0, np.float32)
    heights[10:20, 18:24] = 253.0
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", height=30, width=40, count=1,
                       dtype="float32", crs="EPSG:32631",
                       transform=from_origin(500000.0, 5000030.0, 1.0, 1.0)) as dst:
        dst.write(heights, 1)
    args = ["costmap", "--world", str(tmp_path / "dem.tif"), "--vehicle", "jeep", "--method",
            "binary", "--profile", "smoke"]
    assert main([*args, "--out", str(tmp_path / "out.tif")]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "out.tif")
    with rasterio.open(tmp_path / "out.tif") as src:
        assert src.crs.to_epsg() == 32631 and src.count == 2  # binary: one isotropic layer
        assert src.descriptions[0] == "isotropic (every heading)"
        assert src.bounds == pytest.approx((500000.0, 5000000.0, 500040.0, 5000030.0))
        occ = src.read(2)
        r, c = src.index(500018.0, 5000015.0)  # the block's west face
        assert (occ[r - 3:r + 4, c - 3:c + 4] == OCCUPIED).any()
        assert occ[src.index(500008.0, 5000008.0)] == FREE
    assert main([*args, "--out", str(tmp_path / "nav2" / "jeep"), "--format", "nav2"]) == 0
    assert sorted(p.name for p in (tmp_path / "nav2").glob("*.yaml")) == [
        "jeep_cost.yaml", "jeep_occupancy.yaml"]
    (tmp_path / "into").mkdir()  # a directory: the files go inside it, never beside it
    assert main([*args, "--out", str(tmp_path / "into") + "/", "--format", "nav2"]) == 0
    assert sorted(p.name for p in (tmp_path / "into").glob("*.yaml")) == [
        "jeep_binary_cost.yaml", "jeep_binary_occupancy.yaml"]
    assert not list(tmp_path.glob("into_*"))
    before = (tmp_path / "dem.tif").read_bytes()  # --out the input DEM: refused, kept
    assert main([*args, "--out", str(tmp_path / "." / "dem.tif")]) == 2
    assert "also an input" in capsys.readouterr().err
    assert (tmp_path / "dem.tif").read_bytes() == before
    assert main([*args[:2], str(tmp_path / "none.tif"), *args[3:], "--out", "x.tif"]) == 2
    assert "dgt costmap: error:" in capsys.readouterr().err
    # dgt plan on the same DEM (its maps cached now), start and goal in the file's CRS
    plan = ["plan", *args[1:], "--start", "500005,5000005,0", "--goal", "500035,5000025",
            "--crs-coords", "--json"]
    assert main(plan) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["start"] == [5.0, 5.0, 0.0] and report["goal"] == [35.0, 25.0]
    assert report["found"] and report["world"] == "dem"


def test_dgt_costmap_without_rasterio_says_which_extra_before_any_work(tmp_path, monkeypatch,
                                                                       capsys):
    monkeypatch.setitem(sys.modules, "rasterio", None)
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    np.save(tmp_path / "flat.npy", np.zeros((40, 40), np.float32))
    assert main(["costmap", "--world", str(tmp_path / "flat.npy"), "--vehicle", "jeep",
                 "--method", "binary", "--profile", "smoke", "--out", "x.tif"]) == 2
    assert "pip install 'dgt-kit[geo]'" in capsys.readouterr().err
    assert not any((tmp_path / "data").rglob("*"))  # nothing was built


WRITER = """
import sys
import numpy as np
from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.export import write_geotiff
k, h, w = 8, {side}, {side}
grid = GridSpec((0.0, 0.0), 0.4, (h, w))
occ = np.zeros((h, w), np.uint8)
maps = [np.full((k, h, w), v, np.float32) for v in (0.25, 0.75)]
for i in range({rounds}):
    write_geotiff(sys.argv[1], maps[i % 2], occ, grid)
    print("wrote", flush=True)
"""


def _whole(path) -> float:
    """The one value of every cost band of a GeoTIFF the writer wrote; fails on a file cut
    short, a band of another write, or any band missing."""
    with rasterio.open(path) as src:
        assert src.count == 9
        bands = src.read()
    assert (bands[-1] == 0).all()
    values = np.unique(bands[:-1])
    assert len(values) == 1 and values[0] in (0.25, 0.75), values
    return float(values[0])


def _writer(target, *, side: int = 700, rounds: int = 1000):
    import subprocess

    script = WRITER.format(side=side, rounds=rounds)
    return subprocess.Popen([sys.executable, "-c", script, str(target)],
                            stdout=subprocess.PIPE, text=True)


@pytest.mark.parametrize("signum", ["SIGKILL", "SIGTERM"])
def test_a_costmap_writer_killed_at_random_points_leaves_the_old_file_or_a_whole_new_one(
        tmp_path, signum):
    """A writer rewriting a 9-band GeoTIFF over and over is killed at random moments: the
    target is always a whole file of one write (never zeros, never cut short)."""
    import random
    import signal
    import time

    target = tmp_path / "costmap.tif"
    rng = random.Random(7)
    for _ in range(3):
        proc = _writer(target)
        assert proc.stdout.readline().strip() == "wrote"
        time.sleep(rng.uniform(0.0, 0.6))
        proc.send_signal(getattr(signal, signum))
        proc.wait(timeout=30)
        _whole(target)


def test_two_writers_of_one_path_never_mix_their_bands(tmp_path):
    target = tmp_path / "costmap.tif"
    procs = [_writer(target, side=300, rounds=6) for _ in range(2)]
    for proc in procs:
        proc.communicate(timeout=120)
        assert proc.returncode == 0
    _whole(target)
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []
    # the user's folder shows what they asked for; the writers' lock is hidden
    assert [p.name for p in tmp_path.iterdir() if not p.name.startswith(".")] == ["costmap.tif"]


@pytest.mark.parametrize("out, said", [
    ("/proc/x/costmap.tif", "cannot write in /proc/x"),
    ("", "--out is empty"),
    ("{tmp}", "is a directory"),
    ("{tmp}/" + "c" * 300 + ".tif", "bytes; at most"),
    ("{tmp}/flat.npy", "also an input"),
])
def test_an_unwritable_out_is_one_line_before_any_work(tmp_path, monkeypatch, capsys, out,
                                                       said):
    from dgt_lib.app import costmap_export

    def no_work(*args, **kwargs):
        raise AssertionError("costmaps built before --out was checked")

    monkeypatch.setattr(costmap_export, "ensure_world_costmaps", no_work)
    monkeypatch.setattr(costmap_export, "load_world", no_work)
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    np.save(tmp_path / "flat.npy", np.zeros((40, 40), np.float32))
    assert main(["costmap", "--world", str(tmp_path / "flat.npy"), "--vehicle", "jeep",
                 "--method", "binary", "--profile", "smoke",
                 "--out", out.format(tmp=tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dgt costmap: error:") and said in err and err.count("\n") == 1


def test_an_interrupted_costmap_says_the_out_file_is_the_old_or_the_whole_new_one(
        tmp_path, monkeypatch, capsys):
    from dgt_lib.app import costmap_export
    from dgt_lib.core.faults import Terminated

    def stopped(*args, **kwargs):
        raise Terminated()

    monkeypatch.setattr(costmap_export, "load_world", stopped)
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    out = tmp_path / "out.tif"
    assert main(["costmap", "--world", "hill", "--vehicle", "jeep", "--profile", "smoke",
                 "--out", str(out)]) == 143
    err = capsys.readouterr().err
    assert f"{out} is its earlier file (or none) or the whole new one" in err
    assert "everything finished so far" not in err


def test_nav2_out_that_is_a_directory_gets_the_files_inside(tmp_path):
    cost, occ = synthetic()
    (tmp_path / "maps").mkdir()
    written = write_nav2(tmp_path / "maps", cost, occ, GRID)
    assert {p.parent for p in written} == {tmp_path / "maps"}
    assert written[0].name == "costmap_heading0.yaml"
