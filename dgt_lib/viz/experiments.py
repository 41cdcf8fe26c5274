"""Figures of notebooks 06–08 (Experiments 1–3) and of the results report.

Paper: Experiments → Experiment 1 (hill), Experiment 2 (ridge), Experiment 3
(multi-task), Experimental Protocol, Tables I and II.

Queries on a world figure, every method's planned and driven path for one query,
where failed trials ended (marker by reason, colour by method), speed against time per
method, and success rates with Wilson 95 % intervals beside the paper's. Methods are
shown by their labels (:data:`~dgt_lib.mapping.methods.METHOD_LABELS`:
DGT-Map, DGT-Map(Iso), DGT-Map(ST), Slope-Based, Binary), never by their code keys.
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.legend import Legend
from matplotlib.lines import Line2D

from dgt_lib.mapping.methods import METHOD_LABELS, METHODS
from dgt_lib.navigation.outcome import REASONS
from dgt_lib.viz.common import METHOD_COLORS
from dgt_lib.world.worlds import World


def plot_queries(ax, queries) -> None:
    """Start poses (arrows) and goals (stars) of experiment queries on a world figure."""
    for q in queries:
        x, y, yaw = q.start
        ax.arrow(x, y, 4 * np.cos(yaw), 4 * np.sin(yaw), width=0.6, color="lime")
        ax.plot(*q.goal, "*", color="yellow", ms=10, mec="k")


FAILURE_MARKERS: dict[str, str] = {"immobilized": "X", "flipped": "v", "timeout": "s",
                                   "no_path": "o", "diverged": "D", "error": "P"}
"""The marker of each failure reason (:data:`~dgt_lib.navigation.outcome.REASONS`)."""


def end_position(result) -> tuple[float, float]:
    """Where a trial ended [m]: the driven track's last (x, y), or the start without one
    (no path, or an error before driving)."""
    if len(result.trajectory):
        return float(result.trajectory[-1, 1]), float(result.trajectory[-1, 2])
    return float(result.task.query.start[0]), float(result.task.query.start[1])


def plot_failures(ax, results, legend: bool = True) -> list:
    """Mark where each failed trial of ``results`` ended (:func:`end_position`): the
    marker says why (:data:`FAILURE_MARKERS`), the colour which method; with ``legend``,
    a legend of the reasons (with counts) and methods, kept beside any later legend.
    Returns the scatter collections, one per reason."""
    failed = [r for r in results if not r.outcome.success]
    artists, handles = [], []
    for reason in (x for x in REASONS if x in FAILURE_MARKERS):
        rs = [r for r in failed if r.outcome.reason == reason]
        if not rs:
            continue
        xy = np.array([end_position(r) for r in rs])
        artists.append(ax.scatter(xy[:, 0], xy[:, 1], marker=FAILURE_MARKERS[reason], s=70,
                                  c=[METHOD_COLORS[r.task.method] for r in rs],
                                  edgecolors="k", linewidths=0.8, zorder=5))
        handles.append(Line2D([], [], ls="", marker=FAILURE_MARKERS[reason], color="k",
                              mfc="white", label=f"{reason.replace('_', ' ')} ({len(rs)})"))
    if legend and handles:
        methods = [m for m in METHODS if any(r.task.method == m for r in failed)]
        handles += [Line2D([], [], ls="", marker="s", color=METHOD_COLORS[m],
                           label=METHOD_LABELS[m]) for m in methods]
        ax.add_artist(Legend(ax, handles, [h.get_label() for h in handles], loc="upper left",
                             fontsize=7, title="failed trials ended", title_fontsize=7))
    return artists


def plot_failure_map(world: World, result, queries: bool = False):
    """Every failed trial's end position over the world's terrain, one panel per vehicle
    (:func:`plot_failures`); with ``queries``, each query's straight line start → goal."""
    vehicles = sorted({r.task.vehicle for r in result.results})
    fig, axes = plt.subplots(1, len(vehicles), figsize=(6.5 * len(vehicles), 6), squeeze=False)
    for ax, v in zip(axes[0], vehicles, strict=True):
        rs = [r for r in result.results if r.task.vehicle == v]
        ax.imshow(world.heights, origin="lower", extent=world.grid.extent, cmap="terrain")
        if queries:
            for q in {r.task.query for r in rs}:
                ax.plot([q.start[0], q.goal[0]], [q.start[1], q.goal[1]], color="k", lw=0.6,
                        alpha=0.5)
        plot_failures(ax, rs)
        n_failed = sum(not r.outcome.success for r in rs)
        ax.set_title(f"{result.name}: {v}, where the {n_failed} failed trials ended")
    fig.tight_layout()
    return fig


def plot_planned_paths(ax, world: World, maps, result, label: str, index: int | None = None):
    """Every method's planned path for one query (the first with ``label``, or trial
    ``index``) over the terrain and occupancy; success ✓ / failure ✗ in the legend, and
    where each failed trial ended (:func:`plot_failures`)."""
    ax.imshow(world.heights, origin="lower", extent=world.grid.extent, cmap="terrain")
    occ = np.ma.masked_equal(maps.occupancy, 0)
    ax.imshow(occ, origin="lower", extent=maps.grid.extent, cmap="gray_r", vmin=0, vmax=2,
              alpha=0.5)
    picked = [r for r in result.results if r.task.query.label == label
              and (index is None or r.task.index == index)]
    if index is None and picked:
        first = picked[0].task.index
        picked = [r for r in picked if r.task.index == first]
    for r in picked:
        mark = "✓" if r.outcome.success else f"✗ {r.outcome.reason}"
        name = f"{METHOD_LABELS[r.task.method]} ({r.route or 'no path'}) {mark}"
        if len(r.path):
            ax.plot(r.path[:, 0], r.path[:, 1], color=METHOD_COLORS[r.task.method], lw=2,
                    label=name)
        else:
            ax.plot([], [], color=METHOD_COLORS[r.task.method], label=name)
        if len(r.trajectory):
            ax.plot(r.trajectory[:, 1], r.trajectory[:, 2], ":", color=METHOD_COLORS[r.task.method],
                    lw=1)
    if picked:
        q = picked[0].task.query
        plot_queries(ax, [q])
    plot_failures(ax, picked)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(f"{label}: planned (solid) and driven (dotted)")


def plot_trial_speeds(result, label: str | None = None):
    """Speed [m/s] against time of the executed trials, one panel per method."""
    methods = [m for m in METHOD_COLORS if any(r.task.method == m for r in result.results)]
    fig, axes = plt.subplots(1, len(methods), figsize=(4 * len(methods), 3.2), sharey=True,
                             squeeze=False)
    for ax, m in zip(axes[0], methods, strict=True):
        for r in result.results:
            if r.task.method == m and (label is None or r.task.query.label == label) \
                    and len(r.trajectory):
                ax.plot(r.trajectory[:, 0], r.speed, color=METHOD_COLORS[m],
                        alpha=0.9 if r.outcome.success else 0.5,
                        ls="-" if r.outcome.success else "--")
        ax.set_title(METHOD_LABELS[m])
        ax.set_xlabel("time [s]")
    axes[0, 0].set_ylabel("speed [m/s] (dashed: failed)")
    fig.tight_layout()
    return fig


def plot_success_rates(result, paper: Mapping | None = None):
    """Success rate per method with Wilson 95 % intervals (bars), the paper's SR as dots."""
    from dgt_lib.evaluation.statistics import wilson_interval

    vehicles = sorted({r.task.vehicle for r in result.results})
    fig, axes = plt.subplots(1, len(vehicles), figsize=(6 * len(vehicles), 3.8), squeeze=False)
    for ax, v in zip(axes[0], vehicles, strict=True):
        counts = result.counts(v)
        names = list(counts)
        sr = np.array([100 * k / n for k, n in counts.values()])
        ci = np.array([wilson_interval(k, n) for k, n in counts.values()]) * 100
        x = np.arange(len(names))
        ax.bar(x, sr, color=[METHOD_COLORS[m] for m in names],
               yerr=[sr - ci[:, 0], ci[:, 1] - sr], capsize=4, label="ours (Wilson 95 %)")
        if paper and v in paper:
            p = paper[v]
            ps = [100 * p.k[m] / p.n if m in p.k else np.nan for m in names]
            ax.plot(x, ps, "ko", label=f"paper (n = {p.n})")
        ax.set_xticks(x, [METHOD_LABELS[m] for m in names], rotation=20)
        ax.set_ylim(0, 105)
        ax.set_ylabel("success rate [%]")
        ax.set_title(f"{result.name}: {v}, n = {next(iter(counts.values()))[1]}")
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


QUERY_FATES = {"kept": ("k", "-", 1.6, "kept"),
               "hazard": ("0.45", ":", 0.9, "too little hazard on the line"),
               "infeasible": ("tab:red", "--", 0.9, "no feasible path"),
               "footprint": ("tab:purple", ":", 0.6, "start or goal in an obstacle"),
               "off_map": ("tab:orange", ":", 0.6, "goal off the map")}
"""How :func:`plot_query_draw` draws each fate of a candidate: colour, line, width, legend."""


def plot_query_draw(world: World, hazard_mask: np.ndarray, draw, title: str = ""):
    """Every candidate of a query draw (``QueryDraw.tried``) as its straight line on the
    world's heights with the hazard cells (red), styled by its fate (:data:`QUERY_FATES`)."""
    _, ax = plt.subplots(figsize=(7, 6.5))
    ax.imshow(world.heights, origin="lower", extent=world.grid.extent, cmap="terrain")
    ax.imshow(np.ma.masked_equal(hazard_mask, False), origin="lower", extent=world.grid.extent,
              cmap="autumn", alpha=0.6)
    shown = set()
    for start, goal, fate in sorted(draw.tried, key=lambda t: t[2] == "kept"):
        colour, style, width, label = QUERY_FATES[fate]
        count = draw.rejected.get(fate, len(draw.queries))
        ax.plot([start[0], goal[0]], [start[1], goal[1]], color=colour, ls=style, lw=width,
                label=None if fate in shown else f"{label} ({count})")
        shown.add(fate)
    x0, x1, y0, y1 = world.grid.extent
    ax.set(xlim=(x0, x1), ylim=(y0, y1), xlabel="x [m]", ylabel="y [m]",
           title=title or f"{draw.candidates} candidates, {len(draw.queries)} kept")
    ax.legend(fontsize=8, loc="upper right")
    return ax
