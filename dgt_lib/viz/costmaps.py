"""Figures of notebook 04: directional costmap layers C(x, y, θ_k) = 1 − L̂ and the
occupancy map.

Every map is drawn in world metres (``x [m]``, ``y [m]``, the grid's extent) with the
costmaps' colour scale (:data:`~dgt_lib.viz.common.COST_CMAP`, 0 = free … 1 =
impassable) and one colourbar per figure; a world passed along has its routes, trees
and landmarks drawn on top. Heading layer k is travel toward θ_k = 2πk/K (k = 0 is +x,
east; counter-clockwise, so k = K/4 is north).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.patches import Patch

from dgt_lib.core.geometry import GridSpec, heading_bins
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS
from dgt_lib.mapping.occupancy import FREE, OCCUPIED, UNOBSERVED
from dgt_lib.viz.common import COST_CMAP, COST_LABEL, _overlay
from dgt_lib.world.worlds import World

Crop = tuple[float, float, float, float]
"""(x0, x1, y0, y1) [m]: the part of a map to show."""

OCCUPANCY_COLORS = {FREE: ("free", "white"), OCCUPIED: ("occupied", "black"),
                    UNOBSERVED: ("unobserved", "tab:gray")}
"""Occupancy code → (legend name, colour)."""


def _metres(ax) -> None:
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def _layer(cost: np.ndarray, k: int) -> np.ndarray:
    """Heading layer k of a (K, H, W) costmap; the only layer of a direction-free one."""
    return cost[min(k, len(cost) - 1)]


def plot_cost_layer(ax, layer: np.ndarray, grid: GridSpec, *, title: str = "",
                    world: World | None = None, crop: Crop | None = None,
                    landmark_labels: bool = False):
    """One (H, W) cost layer in [0, 1] on ``grid`` (metres, magma 0–1), with the world's
    routes and landmarks (``landmark_labels``: their names) on top when given;
    ``crop``: (x0, x1, y0, y1) [m] to zoom in. Returns the image (for a colourbar)."""
    im = ax.imshow(layer, origin="lower", extent=grid.extent, cmap=COST_CMAP, vmin=0, vmax=1)
    if world is not None:
        _overlay(ax, world, trees=False, labels=landmark_labels, label_color="white")
    ax.set_xlim(crop[:2] if crop else grid.extent[:2])
    ax.set_ylim(crop[2:] if crop else grid.extent[2:])
    ax.set_aspect("equal")
    _metres(ax)
    ax.set_title(title, fontsize=9)
    return im


def plot_layer_panels(panels: Sequence[Sequence[tuple[str, np.ndarray]]], grid: GridSpec, *,
                      world: World | None = None, crop: Crop | None = None,
                      title: str = "", landmark_labels: bool = False, panel_size: float = 4.0):
    """A figure of cost layers: ``panels`` is rows of (title, (H, W) layer) pairs, all on
    ``grid``, drawn with :func:`plot_cost_layer` and one shared colourbar
    (:data:`~dgt_lib.viz.common.COST_LABEL`); the route legend sits in the first panel
    when a world is given. Returns the Figure."""
    n_rows, n_cols = len(panels), max(len(row) for row in panels)
    x0, x1, y0, y1 = crop or grid.extent
    aspect = min(max((x1 - x0) / (y1 - y0), 0.5), 2.0)  # panel width / height
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(panel_size * aspect * n_cols + 1.0,
                                                      panel_size * n_rows),
                             squeeze=False, constrained_layout=True)
    im = None
    for ax_row, row in zip(axes, panels, strict=True):
        for ax, (name, layer) in zip(ax_row, row, strict=False):
            im = plot_cost_layer(ax, layer, grid, title=name, world=world, crop=crop,
                                 landmark_labels=landmark_labels)
        for ax in ax_row[len(row):]:
            ax.set_visible(False)
    if world is not None and world.routes:
        axes[0, 0].legend(loc="lower right", fontsize=7)
    fig.colorbar(im, ax=axes, shrink=0.8, label=COST_LABEL)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def plot_heading_layers(cost: np.ndarray, grid: GridSpec, *, world: World | None = None,
                        title: str = ""):
    """All K heading layers of one (K, H, W) costmap, two rows, each titled with k and
    θ_k [deg]. Returns the Figure."""
    thetas = np.degrees(heading_bins(len(cost)))
    panels = [(f"k = {k}: θ = {thetas[k]:.0f}°", cost[k]) for k in range(len(cost))]
    half = -(-len(panels) // 2)
    return plot_layer_panels([panels[:half], panels[half:]], grid, world=world, title=title)


def plot_method_layers(maps, vehicle: str, k: int, *, methods: Sequence[str] = METHODS,
                       world: World | None = None, crop: Crop | None = None):
    """Heading layer k of each method's costmap for ``vehicle`` side by side (one row;
    a direction-free map shows its only layer). ``maps``: a
    :class:`~dgt_lib.mapping.world_maps.WorldMaps`. Returns the Figure."""
    theta = np.degrees(heading_bins(_n_headings(maps, vehicle, methods))[k])
    panels = []
    for m in methods:
        cost = maps.costmap(m, vehicle)
        heading = f"θ = {theta:.0f}°" if len(cost) > 1 else "every θ"
        panels.append((f"{METHOD_LABELS[m]}, {heading}", _layer(cost, k)))
    return plot_layer_panels([panels], maps.grid, world=world, crop=crop,
                             title=f"{vehicle}: each method's cost")


def plot_uphill_downhill(maps, vehicle: str, *, uphill: int, downhill: int,
                         methods: Sequence[str] = ("dgt", "isotropic", "single-task", "slope"),
                         world: World | None = None, crop: Crop | None = None):
    """Two rows, heading layer ``uphill`` above layer ``downhill``, one column per
    method (``maps``: a WorldMaps). Returns the Figure."""
    panels = [[(f"{METHOD_LABELS[m]}: {name}"
                + (f" (k = {k})" if len(maps.costmap(m, vehicle)) > 1 else " (every θ)"),
                _layer(maps.costmap(m, vehicle), k))
               for m in methods] for name, k in (("uphill", uphill), ("downhill", downhill))]
    return plot_layer_panels(panels, maps.grid, world=world, crop=crop,
                             title=f"{vehicle}: uphill and downhill layers of each method")


def plot_vehicle_layers(maps, vehicles: Sequence[str], k: int, *, method: str = "dgt",
                        world: World | None = None):
    """One method's heading layer k for each vehicle side by side, landmarks named
    (the paper's jeep vs van figure; ``maps``: a WorldMaps). Returns the Figure."""
    theta = np.degrees(heading_bins(len(maps.costmap(method, vehicles[0])))[k])
    panels = [(f"{v}: θ = {theta:.0f}° (k = {k})", _layer(maps.costmap(method, v), k))
              for v in vehicles]
    return plot_layer_panels([panels], maps.grid, world=world, landmark_labels=True,
                             panel_size=5.0, title=f"{METHOD_LABELS[method]} per vehicle")


def _n_headings(maps, vehicle: str, methods: Sequence[str]) -> int:
    return max(len(maps.costmap(m, vehicle)) for m in methods)


def plot_occupancy(occupancy: np.ndarray, grid: GridSpec, *, world: World | None = None,
                   gradients: np.ndarray | None = None, tau_s: float | None = None):
    """The occupancy map (free / occupied / unobserved, with a legend) in metres; with
    ``gradients`` [m/m] (‖∇H̄‖ sampled on traversable routes) and ``tau_s`` [m/m], their
    histogram and the threshold beside it. Returns the Figure."""
    with_hist = gradients is not None
    fig, axes = plt.subplots(1, 2 if with_hist else 1, figsize=(12 if with_hist else 6, 5),
                             squeeze=False, constrained_layout=True)
    if with_hist:
        ax = axes[0, 0]
        ax.hist(gradients, bins=60, color="tab:blue")
        if tau_s is not None:
            ax.axvline(tau_s, color="r", label=f"τ_s = {tau_s:.3f} m/m")
            ax.legend()
        ax.set_xlabel("‖∇H̄‖ on traversable routes [m/m]")
        ax.set_ylabel("BEV cells")
    ax = axes[0, -1]
    codes = sorted(OCCUPANCY_COLORS)
    cmap = ListedColormap([OCCUPANCY_COLORS[c][1] for c in codes])
    ax.imshow(occupancy, origin="lower", extent=grid.extent, cmap=cmap, vmin=min(codes) - 0.5,
              vmax=max(codes) + 0.5, interpolation="nearest")
    handles = [Patch(facecolor=colour, edgecolor="black", label=name)
               for name, colour in (OCCUPANCY_COLORS[c] for c in codes)]
    if world is not None:
        _overlay(ax, world, trees=False, labels=False)
        handles += ax.get_legend_handles_labels()[0]
    ax.set_xlim(grid.extent[:2])
    ax.set_ylim(grid.extent[2:])
    _metres(ax)
    ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.9)
    ax.set_title("occupancy map" + (f" (τ_s = {tau_s:.3f} m/m)" if tau_s is not None else ""))
    return fig


def plot_heading_explained(mean_height: np.ndarray, grid: GridSpec,
                           steps: Mapping[str, np.ndarray], head: int, *, theta: float,
                           vehicle: str = ""):
    """The steps of one heading layer (from
    :func:`~dgt_lib.mapping.costmap.explain_heading_layer`): the BEV mean height H̄ [m]
    in metres, H̄ rotated so θ [rad] points up (rotated pixels, 0.4 m each), the
    prediction L̂ of the window at each top-left position (a along θ, b across it), and
    C = 1 − L̂ rotated back onto the grid; each with its colourbar. ``head``: the
    vehicle's head index. Returns the Figure."""
    from dgt_lib.perception.bev import HEIGHT

    fig, axes = plt.subplots(1, 4, figsize=(18, 4.5), constrained_layout=True)
    deg = np.degrees(theta)
    ax = axes[0]
    im = ax.imshow(mean_height, origin="lower", extent=grid.extent, cmap="terrain")
    _metres(ax)
    ax.set_title("BEV mean height H̄ (north up)", fontsize=9)
    fig.colorbar(im, ax=ax, shrink=0.8, label="H̄ [m]")
    ax = axes[1]
    im = ax.imshow(steps["rotated"][HEIGHT], cmap="terrain")
    ax.set_xlabel("rotated column [cells]")
    ax.set_ylabel("rotated row [cells]")
    ax.set_title(f"rotated so θ = {deg:.0f}° points up", fontsize=9)
    fig.colorbar(im, ax=ax, shrink=0.8, label="H̄ [m]")
    ax = axes[2]
    im = ax.imshow(steps["field"][head], cmap="viridis", vmin=0, vmax=1)
    ax.set_xlabel("window column b, across θ [cells]")
    ax.set_ylabel("window row a, along θ [cells]")
    ax.set_title(f"L̂ of the window at each position{f' ({vehicle})' if vehicle else ''}",
                 fontsize=9)
    fig.colorbar(im, ax=ax, shrink=0.8, label="locomotion L̂")
    ax = axes[3]
    im = plot_cost_layer(ax, 1.0 - steps["world"][head], grid,
                         title="C = 1 − L̂, rotated back onto the grid")
    fig.colorbar(im, ax=ax, shrink=0.8, label=COST_LABEL)
    return fig
