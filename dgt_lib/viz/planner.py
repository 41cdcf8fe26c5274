"""Figures and tables of notebook 05 (Hybrid A* on a directional costmap) and of
``dgt plan`` (:func:`plot_query`).

Paper: Traversability-Aware Path Planning → Occupancy Map, Directional Cost Lookup,
Hybrid A*.

The three motion primitives and the costmap layer each one reads
(:func:`primitive_lookups`), the cost amplification C' = C(1 + βC), planned paths and
expanded nodes over a world, a table of plans (:func:`plan_table`), and one planning
query's terrain, occupancy and costmap layer with its path.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LightSource

from dgt_lib.viz.common import _overlay
from dgt_lib.world.worlds import World

PRIMITIVES = ("straight", "left", "right")

PRIMITIVE_COLORS = {"straight": "tab:blue", "left": "tab:green", "right": "tab:red"}

PLAN_COLORS = ("crimson", "black", "darkviolet", "white", "gold", "saddlebrown", "magenta")
"""Path colours of :func:`plot_plans` (distinct from the route colours)."""


def primitive_lookups(pose, min_turn_radius_m: float, grid, n_headings: int, *,
                      step_m: float = 1.6, substep_m: float = 0.2) -> dict[str, dict]:
    """The three Hybrid A* primitives from ``pose`` (x, y, θ) [m, m, rad] and the
    costmap layer each one is priced in, computed as :class:`planner.HybridAStar` does.

    Returns {"straight" | "left" | "right": {"curvature" κ [1/m] (left > 0),
    "substeps" (n, 3) poses every ≤ ``substep_m`` along the arc (the collision
    checks; the last is the successor), "cell" and "next_cell" (row, col) of the pose
    and of the successor, "d_cell" (Δrow, Δcol), "theta" θ' = atan2(Δrow, Δcol) [rad]
    (None when the cell does not change) and "k" k* = argmin_k |θ_k − θ'| (the bin of
    the arc's mid heading when the cell does not change)}.
    """
    from dgt_lib.core.geometry import nearest_heading_bin
    from dgt_lib.navigation.planner import arc_poses, travel_heading_bin

    if not min_turn_radius_m > 0:
        raise ValueError(f"min_turn_radius_m must be > 0, got {min_turn_radius_m}")
    n_sub = math.ceil(step_m / substep_m)
    arc_lengths = step_m * np.arange(1, n_sub + 1) / n_sub
    x, y, theta = (float(v) for v in pose)
    row, col = (int(v) for v in grid.xy_to_cell(x, y))
    out = {}
    for name, kappa in zip(PRIMITIVES, (0.0, 1.0 / min_turn_radius_m, -1.0 / min_turn_radius_m),
                           strict=True):
        sub = arc_poses((x, y, theta), kappa, arc_lengths)
        r1, c1 = (int(v) for v in grid.xy_to_cell(sub[-1, 0], sub[-1, 1]))
        d = (r1 - row, c1 - col)
        if d == (0, 0):
            th, k = None, int(nearest_heading_bin(theta + kappa * step_m / 2, n_headings))
        else:
            th, k = math.atan2(*d), int(travel_heading_bin(*d, n_headings))
        out[name] = {"curvature": kappa, "substeps": sub, "cell": (row, col),
                     "next_cell": (r1, c1), "d_cell": d, "theta": th, "k": k}
    return out


def plot_motion_primitives(pose, min_turn_radius_m: float, grid, n_headings: int,
                           footprint: tuple[float, float], *, step_m: float = 1.6,
                           substep_m: float = 0.2, title: str = ""):
    """The paper's planning figure for one expansion: left, the three arcs from ``pose``
    at r_min over the grid cells, their collision sub-steps, the footprint circles at
    the end of the straight arc, and the cell move (Δrow, Δcol) each successor is priced
    by; right, the K heading bins θ_k with each move's θ' and the layer k* it reads.
    Returns the figure."""
    from matplotlib.patches import Circle, Rectangle

    from dgt_lib.core.geometry import heading_bins
    from dgt_lib.core.vehicles import footprint_circles
    from dgt_lib.navigation.planner import arc_poses

    look = primitive_lookups(pose, min_turn_radius_m, grid, n_headings, step_m=step_m,
                             substep_m=substep_m)
    fig, (ax, ax_k) = plt.subplots(1, 2, figsize=(13, 6),
                                   gridspec_kw={"width_ratios": [1.4, 1]})
    x, y, th = (float(v) for v in pose)
    res = grid.resolution
    span = step_m + 0.5 * footprint[0] + 0.6
    ox, oy = grid.origin_xy
    (r_lo, r_hi), (c_lo, c_hi) = grid.xy_to_cell([x - span, x + span], [y - span, y + span])
    for r in range(int(r_lo), int(r_hi) + 2):
        ax.axhline(oy + r * res, color="0.85", lw=0.6, zorder=0)
    for c in range(int(c_lo), int(c_hi) + 2):
        ax.axvline(ox + c * res, color="0.85", lw=0.6, zorder=0)
    r0, c0 = look["straight"]["cell"]
    ax.add_patch(Rectangle((ox + c0 * res, oy + r0 * res), res, res, color="0.6", zorder=1))
    dense = np.linspace(0, step_m, 50)
    for name, item in look.items():
        color = PRIMITIVE_COLORS[name]
        arc = arc_poses(pose, item["curvature"], dense)
        ax.plot(arc[:, 0], arc[:, 1], color=color, lw=2, zorder=3)
        sub = item["substeps"]
        ax.plot(sub[:, 0], sub[:, 1], "o", color=color, ms=3, zorder=4)
        r1, c1 = item["next_cell"]
        ax.add_patch(Rectangle((ox + c1 * res, oy + r1 * res), res, res, fill=False,
                               ec=color, lw=2, zorder=2))
        theta = "—" if item["theta"] is None else f"{math.degrees(item['theta']):.0f}°"
        ax.annotate("", xy=(ox + (c1 + 0.5) * res, oy + (r1 + 0.5) * res),
                    xytext=(ox + (c0 + 0.5) * res, oy + (r0 + 0.5) * res),
                    arrowprops={"arrowstyle": "->", "color": color, "ls": ":"}, zorder=5)
        ax.plot([], [], color=color, lw=2,
                label=f"{name}: Δ(row, col) = {item['d_cell']}, θ' = {theta}, k* = {item['k']}")
    offsets, radius = footprint_circles(*footprint)
    end = look["straight"]["substeps"][-1]
    for o in offsets:
        ax.add_patch(Circle((end[0] + o * math.cos(end[2]), end[1] + o * math.sin(end[2])),
                            radius, fill=False, ls="--", color="0.3", lw=0.8, zorder=2))
    ax.plot([], [], "--", color="0.3", lw=0.8,
            label="footprint circles at the straight successor (collision check)")
    length, width = footprint
    corner = np.array([end[0], end[1]]) + np.array(
        [[math.cos(end[2]), -math.sin(end[2])], [math.sin(end[2]), math.cos(end[2])]]
    ) @ np.array([-length / 2, -width / 2])
    ax.add_patch(Rectangle(tuple(corner), length, width, angle=math.degrees(end[2]),
                           fill=False, color="0.3", lw=1.2, zorder=2))
    ax.annotate("", xy=(x + 0.5 * math.cos(th), y + 0.5 * math.sin(th)), xytext=(x, y),
                arrowprops={"arrowstyle": "-|>", "color": "k"}, zorder=6)
    ax.set_xlim(x - span, x + span)
    ax.set_ylim(y - span, y + span)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title(title or f"primitives from θ = {math.degrees(th):.0f}°: s = {step_m} m, "
                 f"r_min = {min_turn_radius_m:.2f} m, cells {res} m")
    bins = heading_bins(n_headings)
    ax_k.plot(np.cos(np.linspace(0, 2 * np.pi, 200)), np.sin(np.linspace(0, 2 * np.pi, 200)),
              color="0.8")
    used = {item["k"] for item in look.values()}
    for k, b in enumerate(bins):
        ax_k.plot([0, math.cos(b)], [0, math.sin(b)], color="k" if k in used else "0.75",
                  lw=2 if k in used else 1)
        ax_k.annotate(f"k={k}\n{math.degrees(b):.0f}°", (1.18 * math.cos(b), 1.18 * math.sin(b)),
                      ha="center", va="center", fontsize=8)
    for name, item in look.items():
        if item["theta"] is not None:
            t = item["theta"]
            ax_k.annotate("", xy=(0.8 * math.cos(t), 0.8 * math.sin(t)), xytext=(0, 0),
                          arrowprops={"arrowstyle": "->", "color": PRIMITIVE_COLORS[name],
                                      "lw": 2})
    ax_k.set_xlim(-1.45, 1.45)
    ax_k.set_ylim(-1.45, 1.45)
    ax_k.set_aspect("equal")
    ax_k.axis("off")
    ax_k.set_title("layers θ_k (bold: read by an arc); arrows: θ'")
    fig.tight_layout()
    return fig


def plot_cost_amplification(betas: Sequence[float] = (0.0, 10.0, 50.0, 150.0), ax=None):
    """C' = C(1 + βC) against C ∈ [0, 1] for each β (log y axis). Returns the figure."""
    from dgt_lib.navigation.planner import amplified_cost

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    c = np.linspace(0.0, 1.0, 201)
    for beta in betas:
        ax.plot(c, 1.0 + amplified_cost(c, beta), label=f"β = {beta:g}")
    ax.set_yscale("log")
    ax.set_xlabel("cost C")
    ax.set_ylabel("edge cost per metre, 1 + C' = 1 + C(1 + βC)")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    return ax.figure


def plan_table(results: Mapping[str, object]) -> str:
    """Markdown table of :class:`planner.PlanResult` s by name: success, expansions,
    time [s], cost Σ g and length [m] (— where the plan failed)."""
    rows = ["| | found | expansions | time [s] | cost | length [m] |",
            "|---|---|---:|---:|---:|---:|"]
    for name, r in results.items():
        cost, length = (f"{r.cost:.1f}", f"{r.length_m:.1f}") if r.success else ("—", "—")
        rows.append(f"| {name} | {'yes' if r.success else 'no'} | {r.expansions} | "
                    f"{r.time_s:.2f} | {cost} | {length} |")
    return "\n".join(rows)


def plot_plans(world: World, plans: Mapping[str, object], ax=None, *, background=None,
               title: str = "", expanded: bool = False):
    """Planned paths (name → :class:`planner.PlanResult`) over the hill-shaded heights (or
    a (H, W) ``background`` in [0, 1], e.g. one costmap layer), with the world's routes
    and landmarks; ``expanded`` also scatters each plan's expanded nodes. Returns the
    figure."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 6))
    if background is None:
        shade = LightSource(azdeg=315, altdeg=45).hillshade(
            world.heights.astype(np.float64), vert_exag=2.0, dx=world.resolution,
            dy=world.resolution)
        if not expanded:  # expanded nodes show better over grey shading alone
            ax.imshow(world.heights, origin="lower", extent=world.extent, cmap="terrain")
        ax.imshow(shade, origin="lower", extent=world.extent, cmap="gray",
                  alpha=1.0 if expanded else 0.35)
    else:
        ax.imshow(background, origin="lower", extent=world.extent, cmap="magma", vmin=0, vmax=1)
    _overlay(ax, world, trees=False, labels=False)
    widths = np.linspace(3.5, 1.5, max(2, len(plans)))  # wide first: overlapping paths show
    for i, (name, r) in enumerate(plans.items()):
        color = PLAN_COLORS[i % len(PLAN_COLORS)]
        if expanded and len(r.expanded_xy):
            ax.scatter(*r.expanded_xy.T, s=2, color=color, alpha=0.4, lw=0)
        if r.success:
            ax.plot(r.path[:, 0], r.path[:, 1], color=color, lw=widths[i], label=name)
            ax.plot(*r.path[0, :2], "o", color=color, mec="k")
            ax.plot(*r.path[-1, :2], "*", color=color, mec="k", ms=12)
        else:
            ax.plot([], [], color=color, ls=":", label=f"{name} (no path)")
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(title)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax.figure


def plot_query(world: World, maps, cost: np.ndarray, report):
    """One planning query (:class:`dgt_lib.plan_one.QueryReport`): the terrain with its
    occupancy (left) and the method's cost layer of the start heading (right), both with
    the path (when found), the start (dot) and the goal (star), titled by the report's
    first summary line. maps: the world's costmaps (``occupancy`` and ``grid``); cost
    (K, H, W). Returns the figure."""
    from dgt_lib.core.geometry import nearest_heading_bin
    from dgt_lib.mapping.methods import METHOD_LABELS

    fig, ax = plt.subplots(1, 2, figsize=(13, 6))
    ax[0].imshow(world.heights, origin="lower", extent=world.grid.extent, cmap="terrain")
    occ = np.ma.masked_equal(maps.occupancy, 0)
    ax[0].imshow(occ, origin="lower", extent=maps.grid.extent, cmap="gray_r", vmin=0, vmax=2,
                 alpha=0.6)
    ax[0].set_title(f"{world.name}: terrain and occupancy")
    k = int(nearest_heading_bin(report.start[2], cost.shape[0])) if cost.shape[0] > 1 else 0
    im = ax[1].imshow(cost[k], origin="lower", extent=maps.grid.extent, cmap="magma", vmin=0,
                      vmax=1)
    ax[1].set_title(f"{METHOD_LABELS[report.method]} cost, layer k={k}")
    plt.colorbar(im, ax=ax[1], shrink=0.8)
    for a in ax:
        if report.plan.success:
            a.plot(report.plan.path[:, 0], report.plan.path[:, 1], "c-", lw=2)
        a.plot(*report.start[:2], "go")
        a.plot(*report.goal, "r*", ms=12)
    fig.suptitle(report.summary().splitlines()[0])
    fig.tight_layout()
    return fig
