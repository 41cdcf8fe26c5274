"""The global BEV map: back-projection, binning, streaming statistics, gradient."""

import functools

import numpy as np
import pytest
from scipy import ndimage

from dgt_lib.core import artifacts
from dgt_lib.core.camera import CameraIntrinsics, RGBDFrame
from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.occupancy import OCCUPIED, occupancy_map
from dgt_lib.perception.bev import (
    GRADIENT,
    HEIGHT,
    HEIGHT_STD,
    BEVAccumulator,
    BEVMap,
    bev_grid,
    build_bev,
    height_gradient,
)


def plane_frame(position, rotation, intr: CameraIntrinsics, slope=(0.0, 0.0, 0.0), rgb=None,
                max_depth=60.0) -> RGBDFrame:
    """An exact RGB-D frame of the plane z = a·x + b·y + c seen from a camera pose."""
    a, b, c = slope
    f = intr.focal_px
    cu, cv = intr.principal_point
    v, u = np.mgrid[0 : intr.height, 0 : intr.width] + 0.5
    d_cam = np.stack([(u - cu) / f, -(v - cv) / f, -np.ones_like(u)], axis=-1)
    d = d_cam @ np.asarray(rotation).T
    px, py, pz = position
    denom = d[..., 2] - a * d[..., 0] - b * d[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a * px + b * py + c - pz) / denom  # depth along the view axis (d_cam_z = −1)
    depth = np.where((t > 0) & (t < max_depth), t, np.nan).astype(np.float32)
    if rgb is None:
        rgb = np.full((intr.height, intr.width, 3), 128, dtype=np.uint8)
    return RGBDFrame(rgb, depth, intr, np.asarray(position, float), np.asarray(rotation, float))


def look_rotation(heading: float, pitch_down: float) -> np.ndarray:
    """world_from_camera for a camera looking along heading, pitched down (−z = view)."""
    fwd = np.array([np.cos(pitch_down) * np.cos(heading), np.cos(pitch_down) * np.sin(heading),
                    -np.sin(pitch_down)])
    z = -fwd
    x = np.array([np.sin(heading), -np.cos(heading), 0.0])  # image right
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def test_downward_frame_gives_the_expected_cells():
    # 64×64 px looking straight down from 5 m with tan(fovy/2) = 0.8: an 8 m × 8 m
    # footprint centred on (10, 10), i.e. exactly cells 15..34 of a 0.4 m grid.
    intr = CameraIntrinsics(64, 64, 2 * np.arctan(0.8))
    rgb = np.zeros((64, 64, 3), dtype=np.uint8)
    rgb[:, :32, 0] = 255  # left half of the image red
    rgb[:32, :, 1] = 255  # top half green
    frame = plane_frame((10.0, 10.0, 5.0), np.eye(3), intr, rgb=rgb)
    grid = GridSpec((0.0, 0.0), 0.4, (50, 50))
    bev = build_bev(grid, [frame])

    expected = np.zeros((50, 50), bool)
    expected[15:35, 15:35] = True
    assert np.array_equal(bev.observed, expected)
    assert bev.counts.sum() == 64 * 64
    x, y = grid.cell_centers()
    obs = bev.observed
    assert np.allclose(bev.channels[0][obs], (x < 10)[obs])  # image left = west (camera x = +x)
    assert np.allclose(bev.channels[1][obs], (y > 10)[obs])  # image top = north
    assert np.allclose(bev.channels[2], 0.0)
    assert np.allclose(bev.channels[HEIGHT:][:, obs], 0.0, atol=1e-6)
    assert np.all(bev.channels[:, ~obs] == 0.0)


def test_tilted_frame_over_a_slope_recovers_height_and_gradient():
    slope = (0.2, 0.05, 1.0)
    intr = CameraIntrinsics(160, 120, np.deg2rad(60))
    heading = 0.7
    position = (30.0, 30.0, 1.0 + 0.2 * 30 + 0.05 * 30 + 2.0)  # 2 m above the ground
    frame = plane_frame(position, look_rotation(heading, np.deg2rad(30)), intr, slope=slope)
    grid = GridSpec((0.0, 0.0), 0.4, (150, 150))
    bev = build_bev(grid, [frame], max_depth_m=20.0)

    obs = bev.observed
    assert obs.sum() > 300
    x, y = grid.cell_centers()
    ahead = (x - position[0]) * np.cos(heading) + (y - position[1]) * np.sin(heading)
    assert np.all(ahead[obs] > 0), "points land in front of the camera"
    truth = 0.2 * x + 0.05 * y + 1.0
    # Mean of the points in a cell ≈ plane at the points' mean position (≤ 0.2 m off centre).
    assert np.abs(bev.mean_height - truth)[obs].max() < 0.06
    assert bev.height_std[obs].max() < 0.06
    # Central differences of H̄ recover the slope magnitude (m/m) where sampling is dense.
    dense = obs & (bev.counts >= 20)
    assert dense.sum() > 50
    assert np.median(bev.gradient[dense]) == pytest.approx(np.hypot(0.2, 0.05), abs=0.02)


def test_points_outside_grid_and_nonfinite_are_dropped():
    grid = GridSpec((-2.0, -2.0), 0.4, (10, 10))
    acc = BEVAccumulator(grid)
    pts = np.array([[0.1, 0.1, 1.0], [-2.1, 0.0, 5.0], [0.0, 1.99, 2.0], [0.0, 2.0, 9.0],
                    [np.nan, 0.0, 1.0], [0.1, 0.1, np.inf]])
    added = acc.add_points(pts, np.full_like(pts, 0.5))
    assert added == 2 and acc.n_points == 2
    bev = acc.result()
    assert bev.observed.sum() == 2
    r, c = grid.xy_to_cell(0.1, 0.1)
    assert bev.mean_height[r, c] == pytest.approx(1.0)
    assert bev.height_std[r, c] == 0.0  # a single point has std 0


def test_statistics_match_numpy_and_streaming_equals_one_shot():
    rng = np.random.default_rng(3)
    grid = GridSpec((0.0, 0.0), 0.4, (5, 6))
    x, y = rng.uniform(0, 2.4, 5000), rng.uniform(0, 2.0, 5000)
    # A rough tilted plane, far from 0 (tests precision too).
    pts = np.column_stack([x, y, 100.0 + 0.3 * x - 0.2 * y + rng.normal(0, 0.05, 5000)])
    cols = rng.uniform(0, 1, (5000, 3))
    one = BEVAccumulator(grid)
    one.add_points(pts, cols)
    one_shot = one.result()

    halves = [BEVAccumulator(grid), BEVAccumulator(grid)]
    split = rng.uniform(size=5000) < 0.5
    halves[0].add_points(pts[split], cols[split])
    for chunk in np.array_split(np.flatnonzero(~split), 7):  # streamed in chunks
        halves[1].add_points(pts[chunk], cols[chunk])
    merged = halves[0].merge(halves[1]).result()
    assert np.array_equal(merged.counts, one_shot.counts)
    assert np.allclose(merged.channels, one_shot.channels, atol=1e-5)

    r, c = grid.xy_to_cell(pts[:, 0], pts[:, 1])
    sel = (r == 2) & (c == 3)
    # H̄, σ_H: the least-squares plane through the cell's points, at the cell centre.
    cx, cy = grid.cell_to_xy(2, 3)
    design = np.column_stack([np.ones(sel.sum()), pts[sel, 0] - cx, pts[sel, 1] - cy])
    (h, a, b), *_ = np.linalg.lstsq(design, pts[sel, 2], rcond=None)
    resid = pts[sel, 2] - design @ (h, a, b)
    assert one_shot.mean_height[2, 3] == pytest.approx(h, abs=1e-3)
    assert one_shot.height_std[2, 3] == pytest.approx(
        np.sqrt(np.mean(resid**2) + (a * a + b * b) * 0.4**2 / 12), abs=1e-3)
    assert np.allclose(one_shot.channels[:3, 2, 3], cols[sel].mean(axis=0), atol=1e-6)
    # The paper read literally: the mean and std of the points.
    literal = one.result("points")
    assert literal.mean_height[2, 3] == pytest.approx(pts[sel, 2].mean(), abs=1e-4)
    assert literal.height_std[2, 3] == pytest.approx(pts[sel, 2].std(), abs=1e-4)
    with pytest.raises(ValueError, match="estimator"):
        one.result("median")


def test_gradient_on_a_plane_with_holes_and_borders():
    grid = GridSpec((0.0, 0.0), 0.4, (12, 15))
    x, y = grid.cell_centers()
    h = 0.3 * x - 0.1 * y
    observed = np.ones(grid.shape, bool)
    observed[4:7, 5:9] = False  # a hole
    observed[0, 0] = False
    observed[9, 12] = False
    observed[10, 3] = False  # cell (11, 3) now has no observed neighbour along y
    grad = height_gradient(np.where(observed, h, 0.0), observed, 0.4)
    # Central differences inside, one-sided at borders and at the hole: exact on a plane.
    ok = observed.copy()
    ok[11, 3] = False
    assert np.allclose(grad[ok], np.hypot(0.3, 0.1), atol=1e-5)
    assert grad[11, 3] == pytest.approx(0.3)  # the y component is 0 there
    assert np.all(grad[~observed] == 0.0)
    # An observed cell with no observed neighbour has gradient 0.
    lone = np.zeros(grid.shape, bool)
    lone[5, 5] = True
    assert height_gradient(h, lone, 0.4)[5, 5] == 0.0


def tree_scene(rng, trunk_xy, crown_radius: float | None):
    """Jittered flat-ground points plus a 0.1 m-radius, 4 m trunk (and an optional crown)."""
    gx, gy = np.meshgrid(np.arange(0.05, 16, 0.1), np.arange(0.05, 16, 0.1))
    ground = np.column_stack([gx.ravel(), gy.ravel(), rng.normal(0, 0.01, gx.size)])
    tz = rng.uniform(0, 4, 2000)
    ta = rng.uniform(0, 2 * np.pi, 2000)
    trunk = np.column_stack([trunk_xy[0] + 0.1 * np.cos(ta), trunk_xy[1] + 0.1 * np.sin(ta), tz])
    parts = [ground, trunk]
    if crown_radius is not None:  # upper hemisphere of a crown centred 4 m up
        v = rng.normal(size=(6000, 3))
        v[:, 2] = np.abs(v[:, 2])
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        parts.append(np.array([trunk_xy[0], trunk_xy[1], 4.0]) + crown_radius * v)
        # drop ground the crown hides from above
        d = np.hypot(ground[:, 0] - trunk_xy[0], ground[:, 1] - trunk_xy[1])
        parts[0] = ground[d > crown_radius]
    pts = np.concatenate(parts)
    return pts, np.full_like(pts, 0.4)


@pytest.mark.parametrize("crown_radius", [None, 1.5])
def test_tree_is_enclosed_by_high_gradient(crown_radius):
    rng = np.random.default_rng(7)
    grid = GridSpec((0.0, 0.0), 0.4, (40, 40))
    trunk_xy = (8.2, 7.8)  # centre of cell (19, 20)
    pts, cols = tree_scene(rng, trunk_xy, crown_radius)
    acc = BEVAccumulator(grid)
    acc.add_points(pts, cols)
    bev = acc.result()
    r, c = grid.xy_to_cell(*trunk_xy)
    assert bev.mean_height[r, c] > 1.0 and bev.height_std[r, c] > 0.5
    tau = 1.0  # a plausible occupancy threshold τ_s [m/m]
    if crown_radius is None:
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):  # a one-cell spike: its 4 neighbours
            assert bev.gradient[r + dr, c + dc] > 2.0
    # Flat ground far from the tree is free ...
    x, y = grid.cell_centers()
    far = np.hypot(x - trunk_xy[0], y - trunk_xy[1]) > 3.0
    assert np.all(bev.gradient[far] < 0.2)
    # ... and no 4-connected free path leads from it to the trunk.
    labels, _ = ndimage.label(bev.gradient <= tau)
    assert labels[0, 0] != 0 and labels[r, c] != labels[0, 0]


def test_save_load_roundtrip(tmp_path):
    rng = np.random.default_rng(1)
    grid = GridSpec((-3.0, 5.0), 0.4, (7, 9))
    acc = BEVAccumulator(grid)
    pts = np.column_stack([rng.uniform(-3, 0.6, 300), rng.uniform(5, 7.8, 300),
                           rng.normal(size=300)])
    acc.add_points(pts, rng.uniform(size=(300, 3)))
    bev = acc.result()
    path = tmp_path / "bev.npz"
    artifacts.save(path, bev.to_arrays())
    back = BEVMap.from_arrays(artifacts.load(path))
    assert back.grid == grid
    assert np.array_equal(back.channels, bev.channels)
    assert np.array_equal(back.observed, bev.observed)
    assert np.array_equal(back.counts, bev.counts)
    with pytest.raises(ValueError, match="missing"):
        BEVMap.from_arrays({"channels": bev.channels})


def test_bev_grid_covers_an_extent():
    grid = bev_grid((-10.0, 30.0, 5.0, 25.2))
    assert grid.origin_xy == (-10.0, 5.0) and grid.resolution == 0.4
    assert grid.shape == (51, 100)  # 20.2 m → 51 rows (covers y_max), 40 m → 100 columns
    assert grid.contains(29.99, 25.19) and not grid.contains(30.01, 5.0)
    with pytest.raises(ValueError):
        bev_grid((0.0, 0.0, 0.0, 1.0))


def test_bevmap_rejects_mismatched_shapes():
    grid = GridSpec((0.0, 0.0), 0.4, (4, 5))
    with pytest.raises(ValueError):
        BEVMap(grid, np.zeros((6, 5, 4), np.float32), np.zeros((4, 5), bool),
               np.zeros((4, 5), np.int64))
    with pytest.raises(ValueError):
        BEVAccumulator(grid).add_points(np.zeros((3, 2)), np.zeros((3, 2)))


def test_gradient_channel_is_consistent_with_height_channel():
    rng = np.random.default_rng(5)
    grid = GridSpec((0.0, 0.0), 0.4, (20, 20))
    pts = np.column_stack([rng.uniform(0, 8, 20000), rng.uniform(0, 8, 20000),
                           rng.normal(size=20000)])
    acc = BEVAccumulator(grid)
    acc.add_points(pts, np.zeros_like(pts))
    bev = acc.result()
    assert np.array_equal(bev.channels[GRADIENT],
                          height_gradient(bev.channels[HEIGHT], bev.observed, 0.4))
    assert np.all(bev.channels[HEIGHT_STD][bev.observed] > 0)


def test_bev_from_simulator_frames_matches_the_terrain():
    """Integration with dgt_lib.world.simulator: a survey of a hilly world by the RGB-D camera."""
    from dgt_lib.world.simulator import Simulator
    from dgt_lib.world.worlds import from_heightmap

    rng = np.random.default_rng(0)
    heights = ndimage.gaussian_filter(rng.normal(size=(100, 100)), 8) * 40  # ~8 m relief
    tree_xy = (25.0, 12.0)
    world = from_heightmap(heights - heights.min(), 0.4, trees=[(*tree_xy, 0.3, 5.0)])
    sim = Simulator(world, "jeep")
    try:
        state = sim.reset(10.0, 30.0, 0.3)
        onboard = sim.render_rgbd()
        acc = BEVAccumulator(world.grid)
        top = float(world.heights.max()) + 12.0
        for x, y in ((10, 10), (30, 10), (10, 30), (30, 30)):  # nadir views
            acc.add_frame(sim.render_rgbd((np.array([x, y, top]), np.eye(3))))
        for x, y in ((0, 0), (40, 0), (40, 40), (0, 40)):  # oblique views toward the centre
            rot = look_rotation(np.arctan2(20 - y, 20 - x), np.deg2rad(40))
            acc.add_frame(sim.render_rgbd((np.array([x, y, top]), rot)))
    finally:
        sim.close()
    bev = acc.result()

    # The onboard frame sees the ground ahead of the vehicle, where the terrain is.
    pts, _ = onboard.points_world()
    assert len(pts) > 1000
    ahead = ((pts[:, 0] - state.position[0]) * np.cos(state.yaw)
             + (pts[:, 1] - state.position[1]) * np.sin(state.yaw))
    assert np.mean(ahead > 0) > 0.95
    assert np.median(np.abs(pts[:, 2] - world.height_at(pts[:, 0], pts[:, 1]))) < 0.1

    # Acceptance criterion of the global map: coverage ≥ 95 %, median |H̄ − h| ≤ 0.1 m.
    x, y = world.grid.cell_centers()
    x0, x1, y0, y1 = world.interior
    interior = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    assert bev.observed[interior].mean() >= 0.95
    err = np.abs(bev.mean_height - world.heights)[bev.observed]
    assert np.median(err) <= 0.1
    # ‖∇H̄‖ follows the terrain slope away from the tree, and the tree stands out.
    gx, gy = world.gradient()
    dist = np.hypot(x - tree_xy[0], y - tree_xy[1])
    away = bev.observed & (dist > 4.0)
    assert np.median(np.abs(bev.gradient - np.hypot(gx, gy))[away]) < 0.05
    assert bev.gradient[dist < 2.0].max() > 2.0


def test_crop_keeps_cells_and_world_coordinates():
    from dgt_lib.core.geometry import GridSpec
    from dgt_lib.perception.bev import BEVMap

    grid = GridSpec((10.0, -4.0), 0.4, (20, 30))
    ch = np.random.default_rng(0).random((6, 20, 30)).astype(np.float32)
    bev = BEVMap(grid, ch, np.ones((20, 30), bool), np.ones((20, 30), np.int64))
    sub = bev.crop(slice(5, 15), slice(10, 30))
    assert sub.grid.shape == (10, 20)
    np.testing.assert_array_equal(sub.channels, ch[:, 5:15, 10:30])
    np.testing.assert_allclose(sub.grid.cell_to_xy(0, 0), bev.grid.cell_to_xy(5, 10))
    with pytest.raises(ValueError):
        bev.crop(slice(5, 5), slice(0, 3))


def test_sparse_statistics_restore_the_accumulator():
    rng = np.random.default_rng(0)
    grid = GridSpec((0.0, 0.0), 0.4, (50, 60))

    def slope_points(n):
        x, y = rng.uniform(5, 15, n), rng.uniform(5, 15, n)
        return np.column_stack([x, y, 30.0 + 0.4 * x - 0.3 * y + rng.normal(0, 0.02, n)])

    acc = BEVAccumulator(grid)
    points, colours = slope_points(2000), rng.uniform(0, 1, (2000, 3))
    acc.add_points(points, colours)
    sparse = acc.to_sparse()
    assert len(sparse["cells"]) < grid.height * grid.width / 2  # only the touched cells
    restored = BEVAccumulator(grid).add_sparse(sparse).result()
    ref = acc.result()
    np.testing.assert_array_equal(restored.observed, ref.observed)
    np.testing.assert_allclose(restored.channels[3:], ref.channels[3:], atol=1e-4)
    np.testing.assert_allclose(restored.channels[:3], ref.channels[:3], atol=0.5 / 255 + 1e-6)
    # Survey + episode, the episode stored sparsely: the same map as one accumulator.
    survey, survey_colours = slope_points(3000), rng.uniform(0, 1, (3000, 3))
    merged = BEVAccumulator(grid)
    merged.add_points(survey, survey_colours)
    merged.add_sparse(sparse)
    both = BEVAccumulator(grid)
    both.add_points(np.concatenate([survey, points]), np.concatenate([survey_colours, colours]))
    np.testing.assert_allclose(merged.result().channels[3:], both.result().channels[3:],
                               atol=1e-4)
    with pytest.raises(ValueError, match="grid"):
        BEVAccumulator(GridSpec((0.0, 0.0), 0.4, (10, 10))).add_sparse(sparse)
    old_format = {k: sparse[k] for k in ("cells", "count", "rgb", "z", "shape")}
    old_format["m2"] = sparse["m2"][5]
    with pytest.raises(ValueError, match="older format"):
        BEVAccumulator(grid).add_sparse(old_format)


def test_a_cells_colour_does_not_depend_on_who_looked_at_it():
    """Training patches are cut from a BEV built from onboard and survey frames, costmaps
    from survey-only BEVs: the same ground must get the same colour in both. (With
    MuJoCo's headlight the onboard view rendered grass at 0.64× the survey's brightness.)"""
    from dgt_lib.world.rendering import TerrainRenderer
    from dgt_lib.world.simulator import look_at
    from dgt_lib.world.worlds import from_heightmap

    grass = np.array([0.32, 0.50, 0.20], np.float32)
    x = np.arange(150) * 0.4
    heights = np.tile(np.where(x > 30, (x - 30) * np.tan(np.radians(15)), 0.0), (150, 1))
    colors = np.broadcast_to(grass, (150, 150, 3)).copy()
    world = from_heightmap(heights.astype(np.float32), 0.4, colors=colors, name="grass")
    renderer = TerrainRenderer(world, max_depth_m=20.0)
    views = {"survey (nadir)": ((20.0, 30.0, 15.0), (20.0, 30.01, 0.0)),
             "onboard (grazing)": ((5.0, 30.0, 2.0), (15.0, 30.0, 0.0)),
             "oblique 45°": ((5.0, 30.0, 10.0), (15.0, 30.0, 0.0))}
    flat_colour = {}
    for name, (eye, target) in views.items():
        acc = BEVAccumulator(world.grid)
        acc.add_frame(renderer.render(look_at(np.array(eye), np.array(target))), max_depth_m=20.0)
        bev = acc.result()
        cx, _ = world.grid.cell_centers()
        cells = bev.observed & (cx > 6.0) & (cx < 28.0)  # flat ground seen by every view
        assert cells.sum() > 50, name
        flat_colour[name] = bev.channels[:3, cells].mean(axis=1)
    for name, colour in flat_colour.items():
        np.testing.assert_allclose(colour, grass, atol=0.01, err_msg=name)


# ----------------------------------------------------------------------------- slopes
# A cell's H̄ must be the terrain's height at the cell centre, not the mean of wherever its
# few points fell: on a slope g a point d off the centre is g·d higher (±9 cm at 24°).


def test_height_is_the_plane_at_the_cell_centre_wherever_the_points_fall():
    rng = np.random.default_rng(11)
    grid = GridSpec((0.0, 0.0), 0.4, (20, 24))
    a, b = 0.45, -0.2  # a 26° slope [m/m]
    rows, cols = np.mgrid[0:20, 0:24]
    cx, cy = grid.cell_to_xy(rows, cols)
    parts = []
    for x, y in zip(cx.ravel(), cy.ravel(), strict=True):
        n = rng.integers(1, 4)  # 1–3 points a cell, all in one random quarter of it
        qx, qy = rng.choice([-0.1, 0.1], 2)
        parts.append(np.column_stack([x + qx + rng.uniform(-0.1, 0.1, n),
                                      y + qy + rng.uniform(-0.1, 0.1, n)]))
    xy = np.concatenate(parts)
    pts = np.column_stack([xy, 5.0 + a * xy[:, 0] + b * xy[:, 1]])
    acc = BEVAccumulator(grid)
    acc.add_points(pts, np.full_like(pts, 0.5))
    bev = acc.result()
    assert bev.observed.all()
    np.testing.assert_allclose(bev.mean_height, 5.0 + a * cx + b * cy, atol=1e-4)
    # σ_H: the std of a plane's heights over a square cell, whatever the sampling.
    np.testing.assert_allclose(bev.height_std, np.hypot(a, b) * 0.4 / np.sqrt(12), atol=1e-4)
    np.testing.assert_allclose(bev.gradient, np.hypot(a, b), atol=1e-3)
    planes = acc.planes()
    np.testing.assert_allclose(planes.slope_x, a, atol=1e-3)
    np.testing.assert_allclose(planes.slope_y, b, atol=1e-3)
    # The points' mean is off by up to g·0.2 m, ‖∇H̄‖ by up to twice that / 0.4 m.
    literal = acc.result("points")
    assert np.abs(literal.mean_height - (5.0 + a * cx + b * cy)).max() > 0.04
    assert np.abs(literal.gradient - np.hypot(a, b)).max() > 0.1


def test_a_lone_point_or_a_line_of_points_falls_back_to_the_neighbours_slope():
    grid = GridSpec((0.0, 0.0), 0.4, (3, 3))
    acc = BEVAccumulator(grid)
    # One point, off centre, in an otherwise empty map: its height, level.
    acc.add_points(np.array([[0.55, 0.45, 2.0]]), np.full((1, 3), 0.5))
    bev = acc.result()
    assert bev.mean_height[1, 1] == pytest.approx(2.0)
    assert bev.height_std[1, 1] == pytest.approx(0.0, abs=1e-6)
    # Points along a line across x (which fixes no slope along y) in a slope along y.
    acc = BEVAccumulator(grid)
    x = np.linspace(0.02, 1.18, 30)
    for y in (0.1, 0.3, 0.5, 0.7, 0.9, 1.1):  # every cell, on lines at ±0.1 m
        acc.add_points(np.column_stack([x, np.full(30, y), 0.5 * np.full(30, y)]),
                       np.full((30, 3), 0.5))
    planes = acc.planes()
    np.testing.assert_allclose(planes.slope_y, 0.5, atol=1e-3)
    np.testing.assert_allclose(acc.result().mean_height, 0.5 * grid.cell_centers()[1],
                               atol=1e-3)


def test_ground_beside_a_wall_keeps_its_height():
    """A neighbourhood that is no plane (a trunk, crown or cliff beside the cell) must not
    lend its slope to a sparsely sampled ground cell: one point 0.15 m off the centre of
    flat ground next to a 3 m wall would otherwise move H̄ by ~slope·0.15 m."""
    rng = np.random.default_rng(2)
    grid = GridSpec((0.0, 0.0), 0.4, (8, 8))
    cx, cy = grid.cell_centers()
    ground = np.column_stack([cx.ravel() + rng.choice([-0.15, 0.15], cx.size),
                              cy.ravel() + rng.choice([-0.15, 0.15], cx.size),
                              np.zeros(cx.size)])
    wall = np.column_stack([rng.uniform(1.6, 2.0, 400), rng.uniform(0.0, 3.2, 400),
                            rng.uniform(0.0, 3.0, 400)])  # column 4, 3 m tall
    acc = BEVAccumulator(grid)
    acc.add_points(np.concatenate([ground, wall]), np.full((cx.size + 400, 3), 0.5))
    bev = acc.result()
    beside = np.zeros(grid.shape, bool)
    beside[:, [3, 5]] = True
    assert np.abs(bev.mean_height[beside]).max() < 0.01
    assert bev.mean_height[:, 4].min() > 1.0  # the wall stands
    assert bev.gradient[:, [3, 5]].min() > 1.5  # and is enclosed by high gradient


def _ramp(angle_deg: float, azimuth_deg: float, n: int = 100, length_m: float = 16.0):
    """Heights of a ramp of ``angle_deg`` rising towards ``azimuth_deg`` across the map's
    centre over ``length_m``, level before and after (res 0.4 m, n × n cells)."""
    x = (np.arange(n) + 0.5) * 0.4
    gx, gy = np.meshgrid(x, x)
    az = np.radians(azimuth_deg)
    s = (gx - 0.2 * n) * np.cos(az) + (gy - 0.2 * n) * np.sin(az)
    return np.tan(np.radians(angle_deg)) * (np.clip(s, -length_m / 2, length_m / 2)
                                            + length_m / 2)


def _across(profile, n: int = 100, azimuth_deg: float = 30.0):
    """Heights ``profile(u)`` of the distance u [m] across a line through the centre."""
    x = (np.arange(n) + 0.5) * 0.4 - 0.2 * n
    gx, gy = np.meshgrid(x, x)
    az = np.radians(azimuth_deg)
    return profile(-gx * np.sin(az) + gy * np.cos(az))


def _bump(height_m: float, sigma_m: float, n: int = 100):
    """A Gaussian bump 2 m south of the map's centre."""
    x = (np.arange(n) + 0.5) * 0.4 - 0.2 * n
    gx, gy = np.meshgrid(x, x)
    return height_m * np.exp(-0.5 * (gx**2 + (gy + 2.0) ** 2) / sigma_m**2)


def _narrow_ramp(n: int = 100):
    """A 9 m wide 24° ramp up a 6.2 m plateau, between cliffs."""
    x = (np.arange(n) + 0.5) * 0.4
    gx, gy = np.meshgrid(x, x)
    t = np.tan(np.radians(24))
    on = (np.abs(gy - 0.2 * n) <= 4.5) & (gx > 12.0) & (gx < 26.0)
    return np.where(on, t * (gx - 12.0), np.where(gx >= 26.0, 14.0 * t, 0.0))


SLOPE_WORLDS = {
    **{f"ramp {a}° az {az}°": (lambda a=a, az=az: _ramp(a, az), True)
       for a in (10, 20, 28) for az in (0, 35, 120)},
    "ramp 24° az 73°": (lambda: _ramp(24, 73), True),
    "9 m ramp 24°": (_narrow_ramp, True),
    "smooth ridge": (lambda: _across(lambda u: 1.5 * np.exp(-0.5 * (u / 1.5) ** 2)), False),
    "sharp ridge": (lambda: _across(lambda u: np.maximum(0.0, 0.7 - 0.25 * np.abs(u))), True),
    "bump": (lambda: _bump(2.0, 3.0), False),
}
"""Synthetic terrain: heights (100 × 100 cells of 0.4 m) and whether it is piecewise planar
(whose kinks — a ramp's foot and top, cliffs, a sharp crest — the checks leave out)."""


@functools.cache
def _surveyed(name: str):
    """The world, its survey's accumulator (rendered frames, seams and all) and the
    cells to check: observed, ≥ 2 cells from the map's border and from kinks."""
    from dgt_lib.world.rendering import survey_frames
    from dgt_lib.world.worlds import from_heightmap

    make, piecewise_planar = SLOPE_WORLDS[name]
    world = from_heightmap(make(), 0.4, name=name.replace(" ", "_"))
    acc = BEVAccumulator(world.grid)
    for frame in survey_frames(world):
        acc.add_frame(frame)
    h = world.heights.astype(np.float64)
    check = np.zeros(h.shape, bool)
    check[2:-2, 2:-2] = True
    if piecewise_planar:
        kink = np.zeros(h.shape, bool)
        kink[1:-1, :] |= np.abs(h[2:, :] - 2 * h[1:-1, :] + h[:-2, :]) > 1e-3
        kink[:, 1:-1] |= np.abs(h[:, 2:] - 2 * h[:, 1:-1] + h[:, :-2]) > 1e-3
        check &= ~ndimage.binary_dilation(kink, iterations=2)
    return world, acc, check


def _true_gradient(world) -> np.ndarray:
    """‖∇h‖ of the true heights at the cell centres, by the BEV's own rule."""
    return height_gradient(world.heights, np.ones(world.grid.shape, bool), world.grid.resolution)


@pytest.mark.parametrize("name", SLOPE_WORLDS)
def test_bev_is_faithful_on_rendered_slopes(name):
    """Surveyed like every world (nadir frames 20 m up, 1–5 points a cell, frame seams
    across the slopes): H̄ within 3 cm of the terrain and ‖∇H̄‖ within 0.05 of its
    gradient on every observed cell away from the edges and kinks; σ_H within 1 cm of
    the std of the terrain's heights over the cell (‖∇h‖·Δ/√12 for ground planar over a
    cell, as here)."""
    world, acc, check = _surveyed(name)
    bev = acc.result()
    cells = check & bev.observed
    assert cells.sum() > 0.5 * check.sum()
    true_grad = _true_gradient(world)
    assert np.abs(bev.mean_height - world.heights)[cells].max() < 0.03
    assert np.abs(bev.gradient - true_grad)[cells].max() < 0.05
    sigma = true_grad * world.grid.resolution / np.sqrt(12)
    assert np.abs(bev.height_std - sigma)[cells].max() < 0.01


@pytest.mark.parametrize("name", ["ramp 20° az 35°", "ramp 24° az 73°", "ramp 28° az 120°",
                                  "9 m ramp 24°", "smooth ridge", "bump"])
@pytest.mark.parametrize("tau_s", [0.3, 0.512, 0.606])
def test_occupancy_from_the_bev_is_that_of_the_true_heights(name, tau_s):
    """occ(‖∇H̄‖ > τ_s) equals the occupancy of the true heights on every observed cell
    but those within one cell of a true boundary between free and occupied (τ_s = 0.512 and
    0.606: the rule's value with this BEV and with the points' means; the 24° ramps,
    gradient 0.445, must stay free)."""
    world, acc, _ = _surveyed(name)
    bev = acc.result()
    truth = _true_gradient(world) > tau_s
    boundary = (ndimage.binary_dilation(truth, np.ones((3, 3)))
                & ~ndimage.binary_erosion(truth, np.ones((3, 3)), border_value=1))
    occ = occupancy_map(bev, tau_s)
    wrong = bev.observed & ~boundary & ((occ == OCCUPIED) != truth)
    assert wrong.sum() == 0, f"{wrong.sum()} cells wrong at τ_s = {tau_s}"
