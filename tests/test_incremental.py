"""The incremental costmap equals a full recompute of the same map after every update."""

import copy

import cv2
import numpy as np
import pytest

from dgt_lib.beyond.incremental import IncrementalCostmap, changed_cells, changed_mask
from dgt_lib.core.geometry import heading_bins
from dgt_lib.mapping.costmap import directional_costmap, explain_heading_layer
from tests.test_costmap import synthetic_bev

STRIDE = (4, 2)
K = 8
TOL = 1e-5  # the box sums of a part run over other partial sums than the whole's


def every_pixel_predictor(seed: int = 0):
    """Two 'vehicles' whose L depends on every value of the patch (random weights), so a
    window left stale anywhere shows up in the costmap."""
    w = np.random.default_rng(seed).normal(size=(2, 6 * 22 * 7)).astype(np.float32) / 20.0

    def predict(patches: np.ndarray) -> np.ndarray:
        z = patches.reshape(len(patches), -1) @ w.T
        return 1.0 / (1.0 + np.exp(-z))

    return predict


def terrain(shape=(56, 48), seed=1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.normal(size=shape).astype(np.float32), (0, 0), 2) * 3.0


def full(bev, predict):
    return directional_costmap(bev, predict, K, stride=STRIDE, skip_unobserved=True,
                               progress=False)


def explore(heights: np.ndarray, observed: np.ndarray, box) -> tuple:
    """Observe ``box`` too and raise a bump inside it: the map after one more frame."""
    observed = observed.copy()
    observed[box] = True
    heights = heights.copy()
    heights[box] += 0.8
    return heights, observed


@pytest.fixture()
def grown():
    """An incremental costmap of a map whose south-west was observed, and that map."""
    heights = terrain()
    observed = np.zeros(heights.shape, bool)
    observed[:30, :26] = True
    bev = synthetic_bev(heights, observed)
    predict = every_pixel_predictor()
    inc = IncrementalCostmap(bev.grid, predict, 2, K, stride=STRIDE)
    inc.update(bev, changed_cells(None, bev))
    return inc, bev, heights, observed, predict


def test_from_empty_the_first_update_is_the_full_costmap(grown):
    inc, bev, *_, predict = grown
    assert np.abs(inc.cost - full(bev, predict)).max() < TOL


def test_after_a_new_frame_only_part_is_recomputed_and_it_equals_a_full_recompute(grown):
    inc, bev, heights, observed, predict = grown
    new = synthetic_bev(*explore(heights, observed, (slice(24, 36), slice(20, 30))))
    box = changed_cells(bev, new)
    stats = inc.update(new, box)
    expected = full(new, predict)
    assert np.abs(inc.cost - expected).max() < TOL
    assert np.abs(expected - full(bev, predict)).max() > 0.1  # the frame changed costs
    evaluated_by_full = sum(
        int(explain_heading_layer(new, theta, predict, stride=STRIDE,
                                  skip_unobserved=True)["evaluated"].sum())
        for theta in heading_bins(K))
    assert 0 < stats.windows < evaluated_by_full
    # a second frame elsewhere, on top of the first
    newer = synthetic_bev(*explore(new.mean_height, new.observed,
                                   (slice(40, 50), slice(2, 12))))
    inc.update(newer, changed_cells(new, newer))
    assert np.abs(inc.cost - full(newer, predict)).max() < TOL


def test_a_mask_of_two_distant_changes_evaluates_fewer_windows_than_their_box(grown):
    """Two small changes at opposite corners: their bounding box spans the map, the mask
    does not — fewer windows, the same costmap as a full recompute."""
    inc, bev, heights, observed, predict = grown
    h1, o1 = explore(heights, observed, (slice(2, 8), slice(2, 8)))
    new = synthetic_bev(*explore(h1, o1, (slice(22, 28), slice(20, 26))))
    by_box = copy.deepcopy(inc)
    stats_box = by_box.update(new, changed_cells(bev, new))
    stats_mask = inc.update(new, changed_mask(bev, new))
    expected = full(new, predict)
    assert np.abs(inc.cost - expected).max() < TOL
    assert np.abs(by_box.cost - expected).max() < TOL
    assert 0 < stats_mask.windows < 0.8 * stats_box.windows


def test_refresh_finds_the_changes_itself_and_skips_those_below_its_tolerance(grown):
    """``refresh`` with tolerance 0 is the exact update; with a tolerance, a re-observed
    cell whose values moved by less than it is not evaluated again (what a frame does to
    most cells it sees again), one that moved by more is, and the costmap stays within
    what the skipped change can do."""
    exact, bev, heights, observed, predict = grown
    loose = IncrementalCostmap(bev.grid, predict, 2, K, stride=STRIDE, tolerance=0.05)
    loose.refresh(bev)
    jitter = heights.copy()
    jitter[10:20, 10:20] += 0.01  # a centimetre: re-observation noise
    small = synthetic_bev(jitter, observed)
    assert exact.refresh(small).windows > 0
    assert np.abs(exact.cost - full(small, predict)).max() < TOL
    assert loose.refresh(small).windows == 0
    assert np.abs(loose.cost - full(small, predict)).max() < 0.05
    jitter[10:20, 10:20] += 0.5  # a real change
    large = synthetic_bev(jitter, observed)
    assert loose.refresh(large).windows > 0
    assert np.abs(loose.cost - full(large, predict)).max() < TOL
    with pytest.raises(ValueError, match="tolerance"):
        IncrementalCostmap(bev.grid, predict, 2, K, stride=STRIDE, tolerance=-1.0)


def test_a_dirty_region_too_small_is_caught(grown):
    """The equality above has teeth: leaving changed rows out of the box breaks it (the
    update's own margins absorb a row or two of slack; 4 rows show)."""
    inc, bev, heights, observed, predict = grown
    new = synthetic_bev(*explore(heights, observed, (slice(24, 36), slice(20, 30))))
    rows, cols = changed_cells(bev, new)
    wrong = copy.deepcopy(inc)
    wrong.update(new, (slice(rows.start, rows.stop - 4), cols))
    assert np.abs(wrong.cost - full(new, predict)).max() > 1e-3


def test_nothing_changed_means_nothing_evaluated(grown):
    inc, bev, *_ = grown
    before = inc.cost.copy()
    assert changed_cells(bev, bev) is None
    stats = inc.update(bev, None)
    assert stats.windows == 0 and np.array_equal(inc.cost, before)


def test_unobserved_cells_cost_one_and_the_lattice_path_is_required(grown):
    inc, bev, *_ = grown
    assert np.all(inc.cost[:, :, ~bev.observed] == 1.0)
    with pytest.raises(ValueError, match="stride"):
        IncrementalCostmap(bev.grid, every_pixel_predictor(), 2, K, stride=(1, 1))


def test_a_plan_is_redone_only_when_its_own_cells_got_costlier_in_its_own_direction():
    from dgt_lib.beyond.explore import path_cost_rose
    from dgt_lib.mapping.occupancy import FREE, OCCUPIED

    grid = synthetic_bev(np.zeros((40, 40), np.float32)).grid
    path = np.array([[2.0 + 0.4 * i, 8.0, 0.0] for i in range(20)])  # eastbound, row 20
    before = np.full((8, 40, 40), 0.2, np.float32)
    occupancy = np.full((40, 40), FREE, np.uint8)
    r, c = grid.xy_to_cell(6.0, 8.0)
    after = before.copy()
    after[4, r, c] = 0.9  # westbound layer: not the direction the path drives
    after[0, r + 10, c] = 0.9  # eastbound, but off the path
    assert not path_cost_rose(path, before, after, occupancy, grid, rise=0.3)
    after[0, r, c] = 0.45  # on the path, its direction, but a small rise
    assert not path_cost_rose(path, before, after, occupancy, grid, rise=0.3)
    after[0, r, c] = 0.9
    assert path_cost_rose(path, before, after, occupancy, grid, rise=0.3)
    occupancy[r, c] = OCCUPIED
    assert path_cost_rose(path, before, before, occupancy, grid, rise=0.3)
