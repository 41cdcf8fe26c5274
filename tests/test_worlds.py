"""Worlds: the generated maps have their features, are deterministic, and user height
maps become worlds or clear errors."""

import numpy as np
import pytest

from dgt_lib.core.config import get_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.world.terrain import EXTRA_WORLD_NAMES, WORLD_NAMES, get_world, make_training
from dgt_lib.world.worlds import (
    DIRT,
    ROCK,
    HeightmapError,
    UnknownWorldError,
    from_heightmap,
    load_heightmap,
    polyline_distance,
)
from tests.test_premises import ground

SMOKE = get_profile("smoke")


@pytest.mark.parametrize("name", WORLD_NAMES + EXTRA_WORLD_NAMES)
def test_world_arrays_follow_the_contract(name):
    w = get_world(name, SMOKE)
    H, W = w.grid.shape
    assert w.heights.shape == (H, W) and w.heights.dtype == np.float32
    assert w.colors.shape == (H, W, 3) and w.colors.dtype == np.float32
    assert 0.0 <= w.colors.min() and w.colors.max() <= 1.0
    assert np.all(np.isfinite(w.heights))
    assert w.trees.shape[1] == 4 and len(w.trees) > 0
    assert np.all(w.grid.contains(w.trees[:, 0], w.trees[:, 1]))
    assert 0.2 <= w.resolution <= 0.4
    for x, y in w.landmarks.values():
        assert w.grid.contains(x, y)


def test_unknown_world_lists_valid_names():
    with pytest.raises(UnknownWorldError, match="training, hill, ridge, eval"):
        get_world("moon", SMOKE)


def test_generation_is_deterministic_in_the_seed():
    a, b = make_training(60.0, 0.4, seed=3), make_training(60.0, 0.4, seed=3)
    assert np.array_equal(a.heights, b.heights) and np.array_equal(a.colors, b.colors)
    assert np.array_equal(a.trees, b.trees)
    c = make_training(60.0, 0.4, seed=4)
    assert not np.allclose(a.heights, c.heights)


def test_eval_differs_from_training_and_sizes_follow_the_profile():
    train, ev = get_world("training", SMOKE), get_world("eval", SMOKE)
    assert train.extent[1] == pytest.approx(SMOKE.worlds.training_size_m)
    assert ev.extent[1] == pytest.approx(SMOKE.worlds.eval_size_m)
    assert ev.seed != train.seed
    n = min(train.heights.shape[0], ev.heights.shape[0])
    assert not np.allclose(train.heights[:n, :n], ev.heights[:n, :n])


def test_training_has_the_variety_the_vehicles_must_experience():
    w = get_world("training", SMOKE)
    slope = w.slope_deg()
    weakest = get_vehicle("carla_cola").max_climb_deg
    assert (slope < 5).mean() > 0.05  # flat ground
    assert (slope > weakest + 5).mean() > 0.02  # beyond the weakest climber
    # Paths are brown dirt, steep ground is grey rock: colours carry information.
    is_dirt = np.linalg.norm(w.colors - DIRT, axis=-1) < 0.12
    is_rock = np.linalg.norm(w.colors - ROCK, axis=-1) < 0.12
    assert is_dirt.mean() > 0.02 and is_rock.mean() > 0.01
    assert np.median(slope[is_rock]) > np.median(slope) + 5
    assert len(w.routes) >= 1  # the dirt paths, as polylines


def _profile(w, polyline, step=0.2):
    seg = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.arange(0.0, cum[-1], step)
    x, y = np.interp(s, cum, polyline[:, 0]), np.interp(s, cum, polyline[:, 1])
    z = w.height_at(x, y)
    return s, z, np.degrees(np.arctan(np.abs(np.gradient(z, step))))


def test_hill_routes_a_gentle_and_long_b_short_and_steep():
    w = get_world("hill", SMOKE)
    sa, za, slope_a = _profile(w, w.routes["A"])
    sb, zb, slope_b = _profile(w, w.routes["B"])
    assert sa[-1] > 2 * sb[-1]
    rise = ground(w, "summit") - ground(w, "base")
    assert rise >= 10.0
    weakest = get_vehicle("carla_cola").max_climb_deg
    assert slope_a.max() < weakest - 3
    steep = slope_b > weakest + 5
    assert steep.any() and slope_b.max() < get_vehicle("jeep").max_climb_deg - 10
    # The steep part alone rises at least 8 m (no climbing it on momentum).
    assert np.ptp(zb[steep]) >= 8.0


def test_hill_summit_only_reachable_by_the_routes():
    w = get_world("hill", SMOKE)
    cx, cy = w.landmarks["summit"]
    ang = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    ring = np.stack([cx + 19 * np.cos(ang), cy + 19 * np.sin(ang)], 1)  # plateau r = 14 m
    off_route = np.minimum(polyline_distance(ring, w.routes["A"])[0],
                           polyline_distance(ring, w.routes["B"])[0]) > 7.0
    r, c = w.grid.xy_to_cell(ring[:, 0], ring[:, 1])
    assert off_route.sum() > 500
    # Off the routes the way up is a cliff no vehicle climbs (the jeep's limit is ~43°).
    assert np.all(w.slope_deg()[r, c][off_route] > 50.0)
    assert np.all(w.heights[r, c][off_route] < ground(w, "summit") - 3)


def test_ridge_spans_the_whole_width_with_one_smoothed_section():
    w = get_world("ridge", SMOKE)
    sharp = w.landmarks["sharp_crossing"]
    smooth = w.landmarks["smooth_crossing"]
    assert sharp[1] == smooth[1]
    X, Y = w.grid.cell_centers()
    band = np.abs(Y[:, 0] - sharp[1]) < 0.6
    crest = w.heights[band].max(axis=0)
    r_south, _ = w.grid.xy_to_cell(0.0, sharp[1] - 10)
    r_north, _ = w.grid.xy_to_cell(0.0, sharp[1] + 10)
    beside = np.maximum(w.heights[r_south], w.heights[r_north])
    assert np.all(crest - beside > 0.2)  # no column lets a vehicle by
    for (x, y), flank_max in ((sharp, 16.0), (smooth, 6.0)):
        ys = np.arange(y - 8, y + 8, 0.1)
        z = w.height_at(np.full_like(ys, x), ys)
        flank = np.degrees(np.arctan(np.abs(np.gradient(z, 0.1))))
        assert np.percentile(flank, 90) < flank_max
    ys = np.arange(sharp[1] - 6, sharp[1] + 6, 0.1)
    z = w.height_at(np.full_like(ys, sharp[0]), ys)
    assert 0.55 < z.max() - min(z[0], z[-1]) < 0.95  # the 0.7 m ridge


def test_height_at_is_exact_at_cell_centres_and_bilinear_between():
    h = np.arange(30 * 40, dtype=np.float64).reshape(30, 40) * 0.01
    w = from_heightmap(h, 0.4, origin=(5.0, -2.0))
    X, Y = w.grid.cell_centers()
    assert np.allclose(w.height_at(X, Y), h, atol=1e-5)
    # halfway between cells (r, c) and (r, c + 1)
    assert w.height_at(X[3, 4] + 0.2, Y[3, 4]) == pytest.approx((h[3, 4] + h[3, 5]) / 2)


def test_from_heightmap_keeps_heights_colors_trees():
    rng = np.random.default_rng(0)
    h = rng.uniform(0, 2, (30, 25)).astype(np.float32)
    rgb = rng.integers(0, 256, (30, 25, 3), dtype=np.uint8)
    w = from_heightmap(h, 0.3, colors=rgb, trees=[(3.0, 4.0, 0.2, 5.0)], name="mine")
    assert np.array_equal(w.heights, h) and w.name == "mine"
    assert np.allclose(w.colors, rgb / 255.0)
    assert w.trees.shape == (1, 4)
    assert w.grid.shape == (30, 25) and w.grid.resolution == 0.3


@pytest.mark.parametrize(
    "heights, resolution, message",
    [
        (np.full((30, 30), np.nan), 0.4, "NaN/inf"),
        (np.pad(np.zeros((29, 30)), ((0, 1), (0, 0)), constant_values=np.inf), 0.4, "NaN/inf"),
        (np.zeros((21, 7)), 0.4, "smaller than one"),
        (np.zeros((30, 6)), 0.4, "smaller than one"),
        (np.zeros((30, 30)), 0.0, "resolution must be > 0"),
        (np.zeros((30, 30)), -0.4, "resolution must be > 0"),
        (np.zeros((30, 30, 2)), 0.4, "2-D"),
        (np.zeros(30), 0.4, "2-D"),
        (np.full((30, 30), "a"), 0.4, "real-valued"),
        (np.zeros((30, 30), bool), 0.4, "real-valued"),
    ],
)
def test_bad_heightmaps_are_clear_errors(heights, resolution, message):
    with pytest.raises(HeightmapError, match=message):
        from_heightmap(heights, resolution)


def test_heights_beyond_float32_are_rejected_before_they_reach_mujoco(tmp_path):
    """1e40 is finite as float64 but inf as float32, the world's dtype: it used to pass and
    fail inside MuJoCo ("nan size in geom")."""
    heights = np.zeros((30, 30))
    heights[3, 4] = 1e40
    with pytest.raises(HeightmapError, match="beyond float32"):
        from_heightmap(heights, 0.4)
    np.save(tmp_path / "huge.npy", heights)
    with pytest.raises(HeightmapError, match="beyond float32"):
        load_heightmap(tmp_path / "huge.npy", 0.4)
    with pytest.raises(HeightmapError, match="trees must be finite"):
        from_heightmap(np.zeros((30, 30)), 0.4, trees=[(1e40, 2.0, 0.3, 5.0)])
    assert from_heightmap(heights * 1e-3, 0.4).heights.max() == np.float32(1e37)  # still fine


def test_smallest_valid_map_is_one_patch():
    assert from_heightmap(np.zeros((22, 7)), 0.4).grid.shape == (22, 7)
    with pytest.raises(HeightmapError, match="colors must have shape"):
        from_heightmap(np.zeros((22, 7)), 0.4, colors=np.zeros((7, 22, 3)))


def test_load_heightmap_npy_and_16bit_png(tmp_path):
    import cv2

    h = np.linspace(0, 3, 40 * 30).reshape(40, 30)
    np.save(tmp_path / "map.npy", h)
    w = load_heightmap(tmp_path / "map.npy", 0.4)
    assert np.allclose(w.heights, h, atol=1e-6) and w.name == "map"
    img = np.round(h / 3.0 * 65535).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "map.png"), img[::-1])  # image top row = north edge
    w = load_heightmap(tmp_path / "map.png", 0.4, vertical_scale_m=3.0)
    assert np.allclose(w.heights, h, atol=1e-4)


def test_load_heightmap_bad_files(tmp_path):
    with pytest.raises(HeightmapError, match="not found"):
        load_heightmap(tmp_path / "missing.npy", 0.4)
    (tmp_path / "junk.png").write_bytes(b"not an image")
    with pytest.raises(HeightmapError, match="cannot read"):
        load_heightmap(tmp_path / "junk.png", 0.4, vertical_scale_m=1.0)
    (tmp_path / "junk.npy").write_bytes(b"not an array")
    with pytest.raises(HeightmapError, match="cannot read"):
        load_heightmap(tmp_path / "junk.npy", 0.4)
    (tmp_path / "map.tif").write_bytes(b"")
    with pytest.raises(HeightmapError, match="unsupported"):
        load_heightmap(tmp_path / "map.tif", 0.4)
    import cv2

    cv2.imwrite(str(tmp_path / "ok.png"), np.zeros((30, 30), np.uint16))
    with pytest.raises(HeightmapError, match="vertical_scale_m"):
        load_heightmap(tmp_path / "ok.png", 0.4)


def test_tree_distance():
    w = from_heightmap(np.zeros((30, 30)), 0.4, trees=[(5.0, 5.0, 0.3, 6.0), (9.0, 5.0, 0.2, 5.0)])
    assert w.tree_distance(5.0, 7.0) == pytest.approx(1.7)
    assert np.allclose(w.tree_distance([9.0, 5.0], [6.0, 5.0]), [0.8, -0.3])
    assert np.isinf(from_heightmap(np.zeros((30, 30)), 0.4).tree_distance(1.0, 1.0))


def test_on_route_tells_which_route_a_path_took():
    w = get_world("hill", SMOKE)
    a, b = w.routes["A"], w.routes["B"]
    wobble = np.array([1.5, -1.0])
    assert w.on_route(a + wobble, "A") and not w.on_route(a, "B")
    assert w.on_route(b - wobble, "B") and not w.on_route(b, "A")


def test_features_computed_on_their_window_equal_the_whole_grid_formula():
    """make_training adds each bump and ridge on the box outside which it is exactly zero
    (terrain._window): the world must come out as if every feature covered the whole map."""
    from dgt_lib.core.geometry import GridSpec
    from dgt_lib.world.terrain import _EXP_UNDERFLOW, _window

    grid = GridSpec(origin_xy=(0.0, 0.0), resolution=0.4, shape=(400, 500))
    X, Y = grid.cell_centers()
    rng = np.random.default_rng(7)
    for _ in range(20):
        cx, cy = rng.uniform(-20.0, 220.0, 2)  # centres off the map too
        sig, amp = rng.uniform(0.8, 2.0), rng.uniform(0.2, 0.7)
        whole = amp * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * sig**2))
        part = np.zeros_like(whole)
        w = _window(grid, cx, cy, sig * np.sqrt(2 * _EXP_UNDERFLOW))
        part[w] = amp * np.exp(-((X[w] - cx) ** 2 + (Y[w] - cy) ** 2) / (2 * sig**2))
        np.testing.assert_array_equal(part, whole)
        ang, length, height = rng.uniform(0, np.pi), rng.uniform(8, 30), rng.uniform(0.3, 0.9)
        flank = np.tan(np.radians(rng.uniform(8.0, 20.0)))
        shape = (cx, cy, ang, length, height, flank)
        whole = _ridge(X, Y, *shape)
        part = np.zeros_like(whole)
        w = _window(grid, cx, cy, length / 2 + height / flank)
        part[w] = _ridge(X[w], Y[w], *shape)
        np.testing.assert_array_equal(part, whole)
        assert whole.any() or not part.any()


def _ridge(xs, ys, cx, cy, ang, length, height, flank):
    """make_training's ridge: a triangular cross-section over a length with rounded ends."""
    from dgt_lib.world.worlds import _smoothstep

    u = (xs - cx) * np.cos(ang) + (ys - cy) * np.sin(ang)
    v = -(xs - cx) * np.sin(ang) + (ys - cy) * np.cos(ang)
    along = _smoothstep(length / 2 - np.abs(u), 0.0, 2.0)
    return np.clip(height - np.abs(v) * flank, 0.0, None) * along
