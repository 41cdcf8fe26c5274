"""Figures of notebook 09 and the results report: the measured ground truth C* = 1 − L*
beside the learned costmap layers, and predicted against measured cost.

The ground truth is drawn as dots at its cells, coloured with the costmaps' colour scale
(magma, 0 = free, 1 = impassable) and ringed in white, on top of each method's layer for
the same heading: where a dot's colour differs from the map around it, the map is wrong
there. Unmeasured samples (blocked run-ups) are grey crosses.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from dgt_lib.core.geometry import heading_bins
from dgt_lib.evaluation.accuracy import cost_at
from dgt_lib.evaluation.ground_truth import GroundTruth
from dgt_lib.mapping.methods import METHOD_LABELS
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.viz.common import COST_CMAP, METHOD_COLORS
from dgt_lib.world.worlds import World


def _heading_name(theta: float) -> str:
    names = ("east", "north-east", "north", "north-west", "west", "south-west", "south",
             "south-east")
    return names[int(round(np.degrees(theta) / 45.0)) % 8]


def plot_truth_dots(ax, truth: GroundTruth, k: int, size: float = 40.0):
    """The ground truth of heading layer ``k`` as dots coloured by C* (0–1, magma, white
    ring) and crosses where it was not measured; returns the dots' artist."""
    c = truth.cost[:, k]
    ok = truth.measured[:, k]
    dots = ax.scatter(truth.cells[ok, 0], truth.cells[ok, 1], c=c[ok], cmap=COST_CMAP,
                      vmin=0, vmax=1, s=size, edgecolors="white", linewidths=1.0, zorder=3)
    ax.scatter(truth.cells[~ok, 0], truth.cells[~ok, 1], marker="x", c="0.6", s=size * 0.6,
               zorder=3)
    th = truth.headings[k]
    ax.annotate("", xy=(0.93 + 0.05 * np.cos(th), 0.9 + 0.05 * np.sin(th)),
                xytext=(0.93, 0.9), xycoords="axes fraction",
                arrowprops={"arrowstyle": "->", "color": "cyan", "lw": 2})
    return dots


def plot_ground_truth_beside_layers(world: World, maps: WorldMaps, truth: GroundTruth,
                                    methods: tuple[str, ...] = ("dgt", "single-task", "slope"),
                                    headings: tuple[int, ...] | None = None,
                                    crop: tuple[float, float, float, float] | None = None):
    """One row per heading layer (default: north and south), one column for the ground
    truth over the terrain and one per method's layer, every panel with the ground-truth
    dots. ``crop``: (x0, x1, y0, y1) [m] to zoom in."""
    k_all = truth.locomotion.shape[1]
    headings = headings if headings is not None else (k_all // 4, 3 * k_all // 4)
    grid = maps.grid
    fig, axes = plt.subplots(len(headings), 1 + len(methods),
                             figsize=(3.6 * (1 + len(methods)) + 1.0, 3.5 * len(headings)),
                             squeeze=False, constrained_layout=True)
    thetas = heading_bins(k_all)
    h = world.heights
    relief = max(float(np.ptp(h)), 1e-6)
    for row, k in zip(axes, headings, strict=True):
        ax = row[0]  # the terrain in mid greys, so dark and light dots both show
        ax.imshow(h, origin="lower", extent=world.extent, cmap="gray",
                  vmin=float(h.min()) - 1.5 * relief, vmax=float(h.max()) + 1.5 * relief)
        dots = plot_truth_dots(ax, truth, k)
        ax.set_title(f"measured C* = 1 − L*, {_heading_name(thetas[k])}", fontsize=9)
        for ax, m in zip(row[1:], methods, strict=True):
            layer = maps.costmap(m, truth.vehicle)
            ax.imshow(layer[min(k, len(layer) - 1)], origin="lower", extent=grid.extent,
                      cmap=COST_CMAP, vmin=0, vmax=1)
            plot_truth_dots(ax, truth, k)
            ax.set_title(f"{METHOD_LABELS[m]}, {_heading_name(thetas[k])}", fontsize=9)
        for ax in row:
            ax.set_xlim(crop[:2] if crop else world.extent[:2])
            ax.set_ylim(crop[2:] if crop else world.extent[2:])
            ax.set_aspect("equal")
    fig.colorbar(dots, ax=axes, shrink=0.7, label="cost (0 free … 1 impassable)")
    fig.suptitle(f"{truth.vehicle} on {truth.world}: measured ground truth (dots) on each "
                 "method's layer", fontsize=11)
    return fig


def plot_predicted_vs_measured(truth: GroundTruth, maps: WorldMaps,
                               methods: tuple[str, ...] = ("dgt", "single-task", "slope"),
                               valid: np.ndarray | None = None):
    """Scatter of each method's cost C against the measured C* at every measured sample
    (``valid``: (N, K) which samples to show; default the measured ones), with the
    diagonal; one panel per method."""
    valid = truth.measured if valid is None else valid
    fig, axes = plt.subplots(1, len(methods), figsize=(3.6 * len(methods), 3.6), squeeze=False)
    k = truth.locomotion.shape[1]
    for ax, m in zip(axes[0], methods, strict=True):
        c = cost_at(maps.costmap(m, truth.vehicle), maps.grid, truth.cells, k)
        ax.scatter(truth.cost[valid], c[valid], s=10, alpha=0.5,
                   color=METHOD_COLORS.get(m, "tab:blue"))
        ax.plot([0, 1], [0, 1], "k--", lw=1)
        ax.set_xlim(-0.03, 1.03)
        ax.set_ylim(-0.03, 1.03)
        ax.set_xlabel("measured C* = 1 − L*")
        ax.set_title(METHOD_LABELS[m], fontsize=10)
    axes[0][0].set_ylabel("costmap C = 1 − L̂")
    fig.suptitle(f"{truth.vehicle} on {truth.world}", fontsize=11)
    fig.tight_layout()
    return fig
