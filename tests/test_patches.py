"""Heading-aligned patches: orientation conventions, masks, and the rotated-map equivalence."""

import numpy as np
import pytest
from scipy import ndimage

from dgt_lib.core.geometry import GridSpec
from dgt_lib.perception.bev import GRADIENT, HEIGHT, N_CHANNELS, BEVMap, height_gradient
from dgt_lib.perception.patches import (
    PATCH_COLS,
    PATCH_RES,
    PATCH_ROWS,
    extract_patches,
    forward_grade,
    patch_offsets,
    rotate_map,
    sliding_windows,
    unrotate_map,
    window_counts,
)


def make_bev(grid: GridSpec, height: np.ndarray, observed=None, rng=None) -> BEVMap:
    """A BEVMap with the given H̄, smooth random colours and σ_H, and a consistent ‖∇H̄‖."""
    observed = np.ones(grid.shape, bool) if observed is None else observed
    rng = np.random.default_rng(0) if rng is None else rng
    channels = np.zeros((N_CHANNELS, *grid.shape), np.float32)
    for ch in (0, 1, 2, 4):
        channels[ch] = ndimage.gaussian_filter(rng.uniform(size=grid.shape), 2.0)
    channels[HEIGHT] = height
    channels[GRADIENT] = height_gradient(height, observed, grid.resolution)
    channels[:, ~observed] = 0.0
    return BEVMap(grid, channels, observed, observed.astype(np.int64))


def ramp_bev(slope_x=0.1, slope_y=0.0) -> BEVMap:
    grid = GridSpec((-20.0, -16.0), PATCH_RES, (80, 100))
    x, y = grid.cell_centers()
    return make_bev(grid, (slope_x * x + slope_y * y).astype(np.float32))


def smooth_bev(seed=0, shape=(60, 70)) -> BEVMap:
    rng = np.random.default_rng(seed)
    grid = GridSpec((3.0, -7.0), PATCH_RES, shape)
    height = ndimage.gaussian_filter(rng.normal(size=shape), 3.0) * 20.0
    observed = np.ones(shape, bool)
    observed[20:26, 30:41] = False
    return make_bev(grid, height.astype(np.float32), observed, rng)


def test_patch_offsets_forward_is_row_0_and_left_is_column_0():
    off = patch_offsets()
    assert off.shape == (PATCH_ROWS, PATCH_COLS, 2)
    assert np.allclose(off[0, :, 0], 4.2) and np.allclose(off[-1, :, 0], -4.2)
    assert np.allclose(off[:, 0, 1], 1.2) and np.allclose(off[:, -1, 1], -1.2)
    assert np.ptp(off[..., 0]) + PATCH_RES == pytest.approx(8.8)
    assert np.ptp(off[..., 1]) + PATCH_RES == pytest.approx(2.8)


def test_ramp_heading_0_rises_toward_top_row_and_heading_pi_toward_bottom():
    bev = ramp_bev(slope_x=0.1)
    patches, observed = extract_patches(bev, np.array([[1.3, 2.1, 0.0], [1.3, 2.1, np.pi]]))
    assert patches.shape == (2, N_CHANNELS, PATCH_ROWS, PATCH_COLS) and observed.all()
    up, down = patches[0, HEIGHT], patches[1, HEIGHT]
    assert np.all(np.diff(up, axis=0) < 0)  # row 0 (ahead, +x) is highest
    assert np.all(np.diff(down, axis=0) > 0)
    assert np.allclose(np.ptp(up, axis=1), 0, atol=1e-5)  # level across the vehicle
    # Bilinear interpolation is exact on a linear field: H̄ = 0.1·(x + forward).
    assert np.allclose(up[:, 3], 0.1 * (1.3 + patch_offsets()[:, 3, 0]), atol=1e-5)
    assert np.allclose(patches[:, GRADIENT], 0.1, atol=1e-5)


def test_column_0_is_the_vehicles_left():
    bev = ramp_bev(slope_x=0.0, slope_y=0.1)  # rises to the north
    east, north = extract_patches(bev, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, np.pi / 2]]))[0]
    # Facing east, north is on the left: column 0 highest.
    assert np.all(np.diff(east[HEIGHT], axis=1) < 0)
    # Facing north, the ramp rises ahead: row 0 highest, level across.
    assert np.all(np.diff(north[HEIGHT], axis=0) < 0)


def test_rotating_map_and_heading_by_90_degrees_gives_the_same_patch():
    bev = smooth_bev(seed=1)
    h, w = bev.grid.shape
    res = bev.grid.resolution
    x0, y0 = bev.grid.origin_xy
    # World rotated by +90° about the origin: (x, y) → (−y, x); new[r', c'] = old[H−1−c', r'].
    grid_rot = GridSpec((-(y0 + h * res), x0), res, (w, h))
    channels_rot = np.ascontiguousarray(np.swapaxes(bev.channels[:, ::-1, :], 1, 2))
    observed_rot = np.ascontiguousarray(bev.observed[::-1, :].T)
    bev_rot = BEVMap(grid_rot, channels_rot, observed_rot, observed_rot.astype(np.int64))

    rng = np.random.default_rng(2)
    n = 40
    poses = np.column_stack([rng.uniform(x0 + 5, x0 + w * res - 5, n),
                             rng.uniform(y0 + 5, y0 + h * res - 5, n),
                             rng.uniform(0, 2 * np.pi, n)])
    poses_rot = np.column_stack([-poses[:, 1], poses[:, 0], poses[:, 2] + np.pi / 2])
    p, o = extract_patches(bev, poses)
    p_rot, o_rot = extract_patches(bev_rot, poses_rot)
    assert np.allclose(p, p_rot, atol=1e-4)
    assert np.array_equal(o, o_rot)
    assert (~o).any() and o.any()  # the hole was crossed by some patches


def test_unobserved_cells_and_off_map_are_flagged():
    bev = smooth_bev(seed=3)
    # Heading 0 with the vehicle between two cell rows in x: patch cells sit on BEV cell centres.
    cx, cy = bev.grid.cell_to_xy(23, 35)
    x = cx + 0.5 * PATCH_RES  # vehicle between cells 35 and 36 (10.5 rows ahead = 10.5 cells)
    patch, observed = extract_patches(bev, np.array([x, cy, 0.0]))
    assert patch.shape == (N_CHANNELS, PATCH_ROWS, PATCH_COLS)
    fwd, left = np.moveaxis(patch_offsets(), -1, 0)
    r, c = bev.grid.xy_to_cell(x + fwd, cy + left)
    assert np.array_equal(observed, bev.observed[r, c])
    assert (~observed).sum() == 6 * 11  # hole rows 20..25 × columns 30..40 of the BEV
    assert np.allclose(patch[:, observed], bev.channels[:, r[observed], c[observed]], atol=1e-5)
    # A pose at the map's corner: off-map cells are unobserved and zero.
    x0, y0 = bev.grid.origin_xy
    patch, observed = extract_patches(bev, np.array([x0 + 0.2, y0 + 0.2, 0.0]))
    fx, fy = x0 + 0.2 + fwd, y0 + 0.2 + left
    outside = ~bev.grid.contains(fx, fy)
    assert outside.any() and not observed[outside].any()
    assert np.all(patch[:, outside & (fx < x0 - 0.4)] == 0)


@pytest.mark.parametrize("theta", [0.0, 0.3, np.pi / 2, 2.5, 5.5])
def test_sliding_window_on_rotated_map_equals_extract_patches(theta):
    bev = smooth_bev(seed=4)
    rotated = rotate_map(bev, theta)
    d = rotated.transform.shape[0]
    assert rotated.channels.shape == (N_CHANNELS, d, d) and rotated.observed.shape == (d, d)
    windows = sliding_windows(rotated.channels)
    masks = sliding_windows(rotated.observed)
    rng = np.random.default_rng(5)
    a = rng.integers(0, windows.shape[1], 300)
    b = rng.integers(0, windows.shape[2], 300)
    poses = rotated.transform.window_pose(a, b)
    on_map = bev.grid.contains(poses[:, 0], poses[:, 1])
    assert on_map.sum() > 30
    a, b, poses = a[on_map], b[on_map], poses[on_map]
    patches, observed = extract_patches(bev, poses)
    assert np.allclose(np.moveaxis(windows[:, a, b], 0, 1), patches, atol=1e-4)
    assert np.array_equal(masks[a, b], observed)
    # The poses carry the heading θ and the window centres map back to the same place.
    assert np.allclose(poses[:, 2], theta)
    row, col = rotated.transform.xy_to_rotated(poses[:, 0], poses[:, 1])
    assert np.allclose(row, a + 10.5) and np.allclose(col, b + 3.0)


def test_window_counts_count_the_true_pixels_under_each_window():
    # a sparse mask (most windows see nothing, some one pixel) and a dense one
    rng = np.random.default_rng(2)
    for density in (0.002, 0.5):
        mask = rng.random((60, 45)) < density
        counts = window_counts(mask)
        windows = sliding_windows(mask)
        assert counts.shape == windows.shape[:2]
        assert np.array_equal(counts, windows.sum(axis=(-2, -1)))
    assert (window_counts(mask) > 0).any() and not window_counts(np.zeros((30, 30), bool)).any()


def test_quarter_turns_are_exact_permutations_and_unrotate_inverts():
    bev = smooth_bev(seed=6)
    for theta in (0.0, np.pi / 2, np.pi, 1.5 * np.pi):
        rotated = rotate_map(bev, theta)
        assert rotated.observed.sum() == bev.observed.sum()
        assert np.allclose(np.sort(rotated.channels[HEIGHT][rotated.observed]),
                           np.sort(bev.mean_height[bev.observed]), atol=1e-5)
        back = unrotate_map(rotated.channels, rotated.transform)
        assert np.allclose(back[:, bev.observed], bev.channels[:, bev.observed], atol=1e-4)
    # A generic angle: resampling twice blurs a little but stays close on a smooth map.
    rotated = rotate_map(bev, 0.9)
    back = unrotate_map(rotated.channels[HEIGHT], rotated.transform)
    interior = ndimage.binary_erosion(bev.observed, iterations=2)
    err = np.abs(back - bev.mean_height)[interior]
    assert np.median(err) < 0.05 * np.std(bev.mean_height[interior])
    # Every map cell (and every window centred on one) fits inside the rotated image.
    row, col = rotated.transform.xy_to_rotated(*bev.grid.cell_centers())
    d = rotated.transform.shape[0]
    assert row.min() >= 10.5 and row.max() <= d - 11.5 and col.min() >= 3 and col.max() <= d - 4


def test_extract_patches_rejects_bad_poses_and_grids():
    bev = smooth_bev()
    with pytest.raises(ValueError):
        extract_patches(bev, np.zeros((4, 2)))
    with pytest.raises(ValueError):
        extract_patches(bev, np.array([[0.0, np.nan, 0.0]]))
    coarse = GridSpec((0.0, 0.0), 1.0, (10, 10))
    with pytest.raises(ValueError, match="0.4 m"):
        extract_patches(make_bev(coarse, np.zeros((10, 10), np.float32)), np.zeros((1, 3)))


def test_many_poses_match_one_by_one():
    bev = smooth_bev(seed=8)
    rng = np.random.default_rng(9)
    poses = np.column_stack([rng.uniform(3, 31, 9000), rng.uniform(-7, 17, 9000),
                             rng.uniform(-np.pi, 3 * np.pi, 9000)])  # > one remap chunk
    patches, observed = extract_patches(bev, poses)
    for k in (0, 4095, 4096, 8999):
        p, o = extract_patches(bev, poses[k])
        assert np.array_equal(p, patches[k]) and np.array_equal(o, observed[k])


def test_forward_grade_reads_the_slope_ahead_with_its_sign():
    """A vehicle on a 0.2 ramp facing up it sees grade +0.2, facing down −0.2, across 0."""
    bev = ramp_bev(slope_x=0.2)
    x, y = 0.0, 0.0
    poses = np.array([[x, y, 0.0], [x, y, np.pi], [x, y, np.pi / 2], [x, y, np.pi / 4]])
    patches, observed = extract_patches(bev, poses)
    assert observed.all()
    np.testing.assert_allclose(forward_grade(patches), [0.2, -0.2, 0.0, 0.2 / np.sqrt(2)],
                               atol=1e-3)
