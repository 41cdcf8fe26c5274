import numpy as np
import pytest

from dgt_lib import rr as dgt_rr
from dgt_lib.core.geometry import GridSpec


def test_recording_with_every_kind_of_entity_verifies(tmp_path):
    grid = GridSpec((0.0, 0.0), 0.4, (30, 40))
    x, y = grid.cell_centers()
    heights = 0.1 * x
    path = tmp_path / "runs" / "demo.rrd"
    with dgt_rr.Recording(path, "test") as rec:
        rec.log_terrain(heights, None, grid)
        channels = np.zeros((6, 30, 40), np.float32)
        channels[3] = heights
        rec.log_bev(channels, np.ones((30, 40), bool))
        rec.log_costmap(np.random.default_rng(0).random((8, 30, 40)), "jeep")
        rec.log_occupancy(np.zeros((30, 40), np.uint8))
        t = np.linspace(0, 5, 20)
        xyz = np.stack([t, t, np.zeros_like(t)], 1)
        rec.log_path("dgt", xyz)
        rec.log_trajectory("trial_0", t, xyz, {"speed": np.full(20, 5.0)})
        rgb = np.zeros((12, 16, 3), np.uint8)
        rec.log_frame("f0", rgb, np.ones((12, 16), np.float32), np.zeros(3), np.eye(3), 10.0)
        rec.log_text("results", "| a | b |\n|---|---|\n| 1 | 2 |")
    assert path.stat().st_size > 1000
    dgt_rr.verify(path)


def test_map_image_puts_north_at_the_top():
    grid_array = np.array([[0, 0], [1, 1]])  # row 1 is further north (larger y)
    assert dgt_rr._map_image(grid_array)[0].tolist() == [1, 1]


@pytest.mark.parametrize("content", [b"garbage", None])
def test_verify_rejects_a_broken_file(tmp_path, content):
    good = tmp_path / "good.rrd"
    with dgt_rr.Recording(good, "t") as rec:
        rec.log_text("x", "hello")
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(content if content is not None else good.read_bytes()[:100])
    with pytest.raises(RuntimeError, match="verify"):
        dgt_rr.verify(bad)
