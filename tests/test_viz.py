"""The computing parts of dgt_lib.viz: footprints, map errors, gallery picks, binned means,
tables. (Pure plotting runs in the notebooks.)"""

import math

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest

from dgt_lib import viz
from dgt_lib.core.camera import CameraIntrinsics
from dgt_lib.core.config import VEHICLES, CollectConfig
from dgt_lib.perception import bev as bev_module
from dgt_lib.perception.bev import BEVMap, bev_grid, bev_quality
from dgt_lib.perception.dataset import TEST, TRAIN, VAL, PatchDataset
from dgt_lib.world.rendering import survey_poses
from dgt_lib.world.simulator import look_at
from dgt_lib.world.worlds import from_heightmap

CAM = CameraIntrinsics(160, 120, math.radians(70.0))


def flat_world(size_cells=100, height=2.0):
    return from_heightmap(np.full((size_cells, size_cells), height), 0.4)


def test_nadir_footprint_is_the_pinhole_rectangle_on_the_ground():
    world = flat_world(height=2.0)
    pose = look_at([20.0, 15.0, 22.0], [20.0, 15.0, 0.0])  # 20 m above the ground
    (x0, x1, y0, y1), = viz.survey_footprints(world, [pose], CAM)
    tan_y = math.tan(math.radians(35.0))
    tan_x = tan_y * 160 / 120
    assert (x1 - x0) / 2 == pytest.approx(20.0 * tan_x)
    assert (y1 - y0) / 2 == pytest.approx(20.0 * tan_y)
    assert (x0 + x1) / 2 == pytest.approx(20.0)
    assert (y0 + y1) / 2 == pytest.approx(15.0)


def test_footprint_of_a_camera_looking_at_the_horizon_is_rejected():
    pose = look_at([20.0, 15.0, 5.0], [40.0, 15.0, 5.0])
    with pytest.raises(ValueError, match="does not look down"):
        viz.survey_footprints(flat_world(), [pose], CAM)


def test_survey_footprints_cover_the_whole_interior():
    world = flat_world(size_cells=150)  # 60 m × 60 m
    poses = survey_poses(world, CollectConfig(survey_altitude_m=15.0, survey_overlap=0.2), CAM)
    boxes = viz.survey_footprints(world, poses, CAM)
    x, y = world.grid.cell_centers()
    covered = np.zeros(x.shape, bool)
    for x0, x1, y0, y1 in boxes:
        covered |= (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    assert covered.all()


def test_height_errors_match_bev_quality_and_skip_unobserved_cells():
    world = from_heightmap(np.add.outer(np.zeros(60), 0.1 * np.arange(60)), 0.4)
    grid = bev_grid(world.grid.extent)
    x, y = grid.cell_centers()
    rng = np.random.default_rng(0)
    channels = np.zeros((6, *grid.shape), np.float32)
    channels[3] = world.height_at(x, y) + rng.normal(0, 0.05, grid.shape)
    observed = rng.random(grid.shape) > 0.2
    bev = BEVMap(grid, channels, observed, observed.astype(np.int64))
    err = viz.height_errors(bev, world)
    assert np.all(np.isnan(err[~observed]))
    assert np.isfinite(err[observed]).mean() > 0.9  # all but the border ring
    assert np.nanmedian(np.abs(err)) == pytest.approx(
        bev_quality(bev, world)["height_median_abs_err_m"], rel=1e-5)


def test_quality_table_prints_coverage_and_error_in_cm():
    text = viz.quality_table({"survey": {"coverage": 0.995, "height_median_abs_err_m": 0.0123}})
    assert "| survey | 99.5% | 1.23 |" in text


def test_gallery_spans_each_vehicles_label_range_in_order():
    labels = np.array([0.5, 0.1, 0.9, 0.3, 0.7, 0.2, 0.8], np.float32)
    vehicle = np.array([0, 0, 0, 0, 0, 3, 3], np.int8)
    picks = viz.gallery_indices(labels, vehicle, per_vehicle=3)
    assert picks["jeep"].tolist() == [1, 0, 2]  # lowest, median, highest
    assert picks["carla_cola"].tolist() == [5, 6]  # only two samples: both, no repeats
    assert len(picks["vw_van"]) == 0
    with pytest.raises(ValueError):
        viz.gallery_indices(labels, vehicle, per_vehicle=0)


def test_binned_mean_against_a_hand_computation():
    x = np.array([-5.0, -4.0, 1.0, 2.0, 3.0, 10.0, 99.0])
    y = np.array([0.2, 0.4, 1.0, 0.0, 0.5, 0.7, 5.0])
    centres, mean, sem, count = viz.binned_mean(x, y, np.array([-6.0, 0.0, 6.0, 10.0]),
                                                min_count=2)
    assert centres.tolist() == [-3.0, 3.0, 8.0]
    assert count.tolist() == [2, 3, 1]  # 10 is the last edge: in the last bin; 99 outside
    assert mean[0] == pytest.approx(0.3)
    assert mean[1] == pytest.approx(0.5)
    assert np.isnan(mean[2])  # fewer than min_count
    assert sem[1] == pytest.approx(np.std([1.0, 0.0, 0.5], ddof=1) / np.sqrt(3))
    with pytest.raises(ValueError):
        viz.binned_mean(x, y, np.array([1.0, 1.0]))


def tiny_dataset():
    labels = np.array([0.9, 0.8, 0.2, 0.1, 0.6, 0.4], np.float32)
    vehicle = np.array([0, 0, 3, 3, 3, 1], np.int8)
    n = len(labels)
    return PatchDataset(
        patches=np.zeros((n, 6, 22, 7), np.float16), observed=np.ones((n, 22, 7), bool),
        labels=labels, vehicle=vehicle, trajectory=np.array([0, 0, 5, 6, 6, 9], np.int32),
        pose=np.zeros((n, 3), np.float32),
        split=np.array([TRAIN, TRAIN, TRAIN, VAL, VAL, TEST], np.int8))


def test_dataset_table_counts_runs_splits_and_labels():
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in viz.dataset_table(tiny_dataset()).splitlines()[2:]}
    assert list(rows) == list(VEHICLES)
    assert rows["jeep"] == ["1", "2", "2 / 0 / 0", "2.0", "0.85", "0%"]
    assert rows["carla_cola"] == ["2", "3", "1 / 2 / 0", "1.5", "0.30", "67%"]
    assert rows["mercedes_van"][:2] == ["0", "0"]


def test_directional_table_splits_patches_by_forward_slope():
    labels = np.array([0.9, 0.5, 0.1, 0.8], np.float32)
    vehicle = np.array([3, 3, 3, 3], np.int8)
    slope = np.array([-12.0, 0.0, 12.0, -20.0])
    text = viz.directional_table(labels, vehicle, slope, threshold_deg=8.0)
    cola = next(line for line in text.splitlines() if line.startswith("| carla_cola"))
    cells = [c.strip() for c in cola.split("|")[2:-1]]
    assert cells == ["0.85 (n = 2)", "0.50 (n = 1)", "0.10 (n = 1)", "-0.75"]
    jeep = next(line for line in text.splitlines() if line.startswith("| jeep"))
    assert "– (n = 0)" in jeep


def test_source_markdown_shows_the_implementation_and_where_it_lives():
    text = viz.source_markdown(bev_module.height_gradient)
    assert text.startswith("`dgt_lib/perception/bev.py`, line ")
    assert "def height_gradient(" in text
    assert text.rstrip().endswith("```")


def test_a_query_draw_is_drawn_with_one_legend_entry_per_fate():
    from dgt_lib.evaluation.queries import Query, QueryDraw

    world = from_heightmap(np.zeros((50, 60)), 0.4, name="flat")
    tried = [((2.0, 2.0, 0.0), (20.0, 15.0), "kept"),
             ((3.0, 5.0, 0.0), (9.0, 4.0), "hazard"),
             ((4.0, 4.0, 0.0), (18.0, 12.0), "hazard"),
             ((1.0, 1.0, 0.0), (5.0, 19.0), "infeasible")]
    draw = QueryDraw([Query(*tried[0][:2], "random")], 4,
                     {"off_map": 0, "footprint": 0, "hazard": 2, "infeasible": 1}, tried)
    ax = viz.plot_query_draw(world, np.zeros((50, 60), bool), draw)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["too little hazard on the line (2)", "no feasible path (1)", "kept (1)"]
    assert len(ax.lines) == 4
