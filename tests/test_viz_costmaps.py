"""Notebook 04's figures (dgt_lib.viz.costmaps) label maps in metres, draw a colourbar for
every colour scale, and give the occupancy map a legend that matches its colours."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest

from dgt_lib import viz
from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.occupancy import FREE, OCCUPIED, UNOBSERVED
from dgt_lib.world.worlds import World

GRID = GridSpec((2.0, 4.0), 0.4, (30, 50))  # 20 m × 12 m from (2, 4)
K = 8


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _world() -> World:
    h, w = GRID.shape
    route = np.array([[3.0, 5.0], [20.0, 15.0]], np.float32)
    return World("toy", GRID, np.zeros((h, w), np.float32), np.zeros((h, w, 3), np.float32),
                 landmarks={"gate": (10.0, 10.0)}, routes={"A": route})


class _Maps:
    """The two things the figures read from a WorldMaps: ``grid`` and ``costmap``."""

    grid = GRID

    def costmap(self, method: str, vehicle: str) -> np.ndarray:
        k = 1 if method in ("isotropic", "binary") else K
        return np.linspace(0, 1, k * 30 * 50, dtype=np.float32).reshape(k, 30, 50)


def _colorbars(fig) -> list:
    return [im.colorbar for ax in fig.axes for im in ax.images if im.colorbar is not None]


def test_cost_layer_is_drawn_in_metres_on_the_grid_with_the_routes():
    fig, ax = plt.subplots()
    im = viz.plot_cost_layer(ax, np.zeros(GRID.shape), GRID, title="t", world=_world())
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "y [m]")
    assert tuple(im.get_extent()) == pytest.approx(GRID.extent)
    assert im.get_clim() == (0, 1) and im.get_cmap().name == viz.COST_CMAP
    assert "route A" in [line.get_label() for line in ax.get_lines()]


def test_heading_layers_have_one_shared_cost_colorbar_and_theta_titles():
    cost = _Maps().costmap("dgt", "jeep")
    fig = viz.plot_heading_layers(cost, GRID, world=_world())
    maps = [ax for ax in fig.axes if ax.images]
    assert len(maps) == K
    assert [ax.get_title() for ax in maps][2] == "k = 2: θ = 90°"
    assert all(ax.get_xlabel() == "x [m]" for ax in maps)
    bars = _colorbars(fig)
    assert len(bars) == 1 and bars[0].ax.get_ylabel() == viz.COST_LABEL
    for k, ax in enumerate(maps):  # each panel shows its own layer
        assert np.array_equal(ax.images[0].get_array(), cost[k])


def test_method_layers_mark_a_direction_free_map():
    fig = viz.plot_method_layers(_Maps(), "jeep", 2, methods=("dgt", "isotropic"))
    titles = [ax.get_title() for ax in fig.axes if ax.images]
    assert titles[0].endswith("θ = 90°") and titles[1].endswith("every θ")
    assert len(_colorbars(fig)) == 1


def test_occupancy_legend_names_each_code_in_the_colour_drawn():
    occ = np.full(GRID.shape, FREE, np.uint8)
    occ[:10] = OCCUPIED
    occ[:, :5] = UNOBSERVED
    fig = viz.plot_occupancy(occ, GRID, world=_world(), gradients=np.array([0.1, 0.2, 0.3]),
                             tau_s=0.35)
    hist, ax = fig.axes[:2]
    assert hist.get_xlabel().endswith("[m/m]")
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "y [m]")
    im = ax.images[0]
    legend = {t.get_text(): h for t, h in zip(ax.get_legend().get_texts(),
                                               ax.get_legend().legend_handles, strict=True)}
    assert {"free", "occupied", "unobserved", "route A"} <= set(legend)
    for code, name in ((FREE, "free"), (OCCUPIED, "occupied"), (UNOBSERVED, "unobserved")):
        drawn = im.cmap(im.norm(code))
        assert np.allclose(legend[name].get_facecolor(), drawn), name


def test_explained_heading_labels_metres_and_rotated_cells_with_a_colorbar_each():
    h, w = GRID.shape
    steps = {"rotated": np.zeros((6, 60, 60)), "field": np.full((2, 39, 54), 0.7),
             "world": np.full((2, h, w), 0.7)}
    fig = viz.plot_heading_explained(np.zeros((h, w)), GRID, steps, 1, theta=np.pi / 4,
                                     vehicle="jeep")
    panels = [ax for ax in fig.axes if ax.images]
    assert len(panels) == 4 and len(_colorbars(fig)) == 4
    assert panels[0].get_xlabel() == panels[3].get_xlabel() == "x [m]"
    assert "[cells]" in panels[1].get_xlabel() and "[cells]" in panels[2].get_ylabel()
    assert "45°" in panels[1].get_title()
    assert np.allclose(panels[3].images[0].get_array(), 0.3)  # C = 1 − L̂
    labels = [bar.ax.get_ylabel() for bar in _colorbars(fig)]
    assert labels == ["H̄ [m]", "H̄ [m]", "locomotion L̂", viz.COST_LABEL]
