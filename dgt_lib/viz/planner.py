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
    costmap layer each one is priced in: the planner's own lookup
    (:meth:`~dgt_lib.navigation.planner.primitives.PrimitiveSet.successor`), from the
    pose's cell as the search's start node has it.

    Returns {"straight" | "left" | "right": {"curvature" κ [1/m] (left > 0),
    "substeps" (n, 3) poses every ≤ ``substep_m`` along the arc (the collision
    checks; the last is the successor), "cell" and "next_cell" (row, col) of the pose
    and of the successor, "d_cell" (Δrow, Δcol), "theta" θ' = atan2(Δrow, Δcol) [rad]
    (None when the cell does not change) and "k" k* = argmin_k |θ_k − θ'| (the bin of
    the arc's mid heading when the cell does not change)}.
    """
    from dgt_lib.navigation.planner.primitives import PrimitiveSet

    if not min_turn_radius_m > 0:
        raise ValueError(f"min_turn_radius_m must be > 0, got {min_turn_radius_m}")
    x, y, theta = (float(v) for v in pose)
    primitives = PrimitiveSet(theta, step_m=step_m, min_turn_radius_m=min_turn_radius_m,
                              substep_m=substep_m, circle_offsets=np.zeros(1),
                              resolution=grid.resolution, theta_bins=1,
                              n_headings=n_headings, origin_xy=grid.origin_xy)
    row, col = (int(v) for v in grid.xy_to_cell(x, y))
    out = {}
    for j, name in enumerate(PRIMITIVES):
        end = primitives.successor(x, y, 0, row, col, j)
        d = (end.row - row, end.col - col)
        out[name] = {"curvature": primitives.curvatures[j],
                     "substeps": primitives.poses(x, y, 0, j), "cell": (row, col),
                     "next_cell": (end.row, end.col), "d_cell": d,
                     "theta": None if d == (0, 0) else math.atan2(*d), "k": end.layer}
    return out


def _draw_cells(ax, grid, x: float, y: float, span: float, cell) -> None:
    """Grid lines within ``span`` [m] of (x, y) and the cell ``cell`` (row, col) filled."""
    from matplotlib.patches import Rectangle

    res, (ox, oy) = grid.resolution, grid.origin_xy
    (r_lo, r_hi), (c_lo, c_hi) = grid.xy_to_cell([x - span, x + span], [y - span, y + span])
    for r in range(int(r_lo), int(r_hi) + 2):
        ax.axhline(oy + r * res, color="0.85", lw=0.6, zorder=0)
    for c in range(int(c_lo), int(c_hi) + 2):
        ax.axvline(ox + c * res, color="0.85", lw=0.6, zorder=0)
    ax.add_patch(Rectangle((ox + cell[1] * res, oy + cell[0] * res), res, res, color="0.6",
                           zorder=1))


def _draw_primitive(ax, grid, pose, name: str, item: dict, step_m: float) -> None:
    """One arc, its collision sub-steps, its end cell and the cell move it is priced by."""
    from matplotlib.patches import Rectangle

    from dgt_lib.navigation.planner import arc_poses

    res, (ox, oy) = grid.resolution, grid.origin_xy
    color = PRIMITIVE_COLORS[name]
    arc = arc_poses(pose, item["curvature"], np.linspace(0, step_m, 50))
    ax.plot(arc[:, 0], arc[:, 1], color=color, lw=2, zorder=3)
    ax.plot(*item["substeps"][:, :2].T, "o", color=color, ms=3, zorder=4)
    (r0, c0), (r1, c1) = item["cell"], item["next_cell"]
    ax.add_patch(Rectangle((ox + c1 * res, oy + r1 * res), res, res, fill=False, ec=color,
                           lw=2, zorder=2))
    ax.annotate("", xy=(ox + (c1 + 0.5) * res, oy + (r1 + 0.5) * res),
                xytext=(ox + (c0 + 0.5) * res, oy + (r0 + 0.5) * res),
                arrowprops={"arrowstyle": "->", "color": color, "ls": ":"}, zorder=5)
    theta = "—" if item["theta"] is None else f"{math.degrees(item['theta']):.0f}°"
    ax.plot([], [], color=color, lw=2,
            label=f"{name}: Δ(row, col) = {item['d_cell']}, θ' = {theta}, k* = {item['k']}")


def _draw_footprint(ax, end, footprint: tuple[float, float]) -> None:
    """The footprint rectangle and its covering circles at pose ``end`` (x, y, θ)."""
    from matplotlib.patches import Circle, Rectangle

    from dgt_lib.core.vehicle_spec import footprint_circles

    offsets, radius = footprint_circles(*footprint)
    c, s = math.cos(end[2]), math.sin(end[2])
    for o in offsets:
        ax.add_patch(Circle((end[0] + o * c, end[1] + o * s), radius, fill=False, ls="--",
                            color="0.3", lw=0.8, zorder=2))
    ax.plot([], [], "--", color="0.3", lw=0.8,
            label="footprint circles at the straight successor (collision check)")
    length, width = footprint
    corner = np.array(end[:2]) + np.array([[c, -s], [s, c]]) @ np.array([-length / 2,
                                                                          -width / 2])
    ax.add_patch(Rectangle(tuple(corner), length, width, angle=math.degrees(end[2]),
                           fill=False, color="0.3", lw=1.2, zorder=2))


def _draw_heading_bins(ax, look: dict, n_headings: int) -> None:
    """The K layers' headings θ_k on the unit circle (bold: read by an arc) and each
    move's direction θ'."""
    from dgt_lib.core.geometry import heading_bins

    circle = np.linspace(0, 2 * np.pi, 200)
    ax.plot(np.cos(circle), np.sin(circle), color="0.8")
    used = {item["k"] for item in look.values()}
    for k, b in enumerate(heading_bins(n_headings)):
        ax.plot([0, math.cos(b)], [0, math.sin(b)], color="k" if k in used else "0.75",
                lw=2 if k in used else 1)
        ax.annotate(f"k={k}\n{math.degrees(b):.0f}°", (1.18 * math.cos(b), 1.18 * math.sin(b)),
                    ha="center", va="center", fontsize=8)
    for name, item in look.items():
        if item["theta"] is not None:
            t = item["theta"]
            ax.annotate("", xy=(0.8 * math.cos(t), 0.8 * math.sin(t)), xytext=(0, 0),
                        arrowprops={"arrowstyle": "->", "color": PRIMITIVE_COLORS[name],
                                    "lw": 2})
    ax.set_xlim(-1.45, 1.45)
    ax.set_ylim(-1.45, 1.45)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title("layers θ_k (bold: read by an arc); arrows: θ'")


def plot_motion_primitives(pose, min_turn_radius_m: float, grid, n_headings: int,
                           footprint: tuple[float, float], *, step_m: float = 1.6,
                           substep_m: float = 0.2, title: str = ""):
    """The paper's planning figure for one expansion: left, the three arcs from ``pose``
    at r_min over the grid cells, their collision sub-steps, the footprint circles at
    the end of the straight arc, and the cell move (Δrow, Δcol) each successor is priced
    by; right, the K heading bins θ_k with each move's θ' and the layer k* it reads.
    Returns the figure."""
    look = primitive_lookups(pose, min_turn_radius_m, grid, n_headings, step_m=step_m,
                             substep_m=substep_m)
    fig, (ax, ax_k) = plt.subplots(1, 2, figsize=(13, 6),
                                   gridspec_kw={"width_ratios": [1.4, 1]})
    x, y, th = (float(v) for v in pose)
    span = step_m + 0.5 * footprint[0] + 0.6
    _draw_cells(ax, grid, x, y, span, look["straight"]["cell"])
    for name, item in look.items():
        _draw_primitive(ax, grid, pose, name, item, step_m)
    _draw_footprint(ax, look["straight"]["substeps"][-1], footprint)
    ax.annotate("", xy=(x + 0.5 * math.cos(th), y + 0.5 * math.sin(th)), xytext=(x, y),
                arrowprops={"arrowstyle": "-|>", "color": "k"}, zorder=6)
    ax.set_xlim(x - span, x + span)
    ax.set_ylim(y - span, y + span)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title(title or f"primitives from θ = {math.degrees(th):.0f}°: s = {step_m} m, "
                 f"r_min = {min_turn_radius_m:.2f} m, cells {grid.resolution} m")
    _draw_heading_bins(ax_k, look, n_headings)
    fig.tight_layout()
    return fig


def plot_cost_amplification(betas: Sequence[float] = (0.0, 10.0, 50.0, 150.0)):
    """C' = C(1 + βC) against C ∈ [0, 1] for each β (log y axis). Returns the figure."""
    from dgt_lib.navigation.planner import amplified_cost

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
    """One planning query (:class:`dgt_lib.app.query.QueryReport`): the terrain with its
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


OUTCOME_COLORS = {"pushed": "tab:green", "collides": "tab:red", "closed": "0.5",
                  "not cheaper": "tab:orange", "unreachable": "tab:purple"}
"""Colours of :func:`plot_expansions` by what became of a primitive."""


def plot_expansions(world: World, expansions: Sequence, *, title: str = "",
                    margin_m: float = 6.0):
    """The first steps of a Hybrid A* search (:class:`planner.Expansion` s from
    ``Search.steps()``) over the hill-shaded heights: each popped node (numbered in
    expansion order for the first 10) and a segment to the end of each of its three
    primitives, coloured by what became of it (pushed, collides, closed, not cheaper).
    Zoomed to the expanded area plus ``margin_m``. Returns the figure."""
    _, ax = plt.subplots(figsize=(7, 6.5))
    shade = LightSource(azdeg=315, altdeg=45).hillshade(
        world.heights.astype(np.float64), vert_exag=2.0, dx=world.resolution,
        dy=world.resolution)
    ax.imshow(shade, origin="lower", extent=world.extent, cmap="gray", alpha=0.8)
    seen = set()
    for i, step in enumerate(expansions):
        node = step.node
        for p in step.primitives:
            label = p.outcome if p.outcome not in seen else None
            seen.add(p.outcome)
            ax.plot([node.x, p.x], [node.y, p.y], color=OUTCOME_COLORS[p.outcome], lw=1.2,
                    label=label)
        ax.plot(node.x, node.y, "o", color="k", ms=3)
        if i < 10:
            ax.annotate(str(i), (node.x, node.y), fontsize=7, xytext=(2, 2),
                        textcoords="offset points")
    xy = np.array([(s.node.x, s.node.y) for s in expansions]).reshape(-1, 2)
    if len(xy):
        ax.set_xlim(xy[:, 0].min() - margin_m, xy[:, 0].max() + margin_m)
        ax.set_ylim(xy[:, 1].min() - margin_m, xy[:, 1].max() + margin_m)
    ax.set_aspect("equal")
    ax.legend(fontsize=8, loc="upper right", title="primitive")
    ax.set_title(title or f"the first {len(expansions)} expansions")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax.figure


def expansion_table(expansions: Sequence) -> str:
    """Markdown table of Hybrid A* steps: per expansion, the popped node (x, y, g) and,
    per primitive, the cell move, the layer k* read, the cost C there, g, f and what
    became of it."""
    rows = ["| step | node (x, y) [m], g | primitive | Δ(row, col) | k* | C | g | f | outcome |",
            "|---:|---|---|---|---:|---:|---:|---:|---|"]
    for i, step in enumerate(expansions):
        n = step.node
        for p in step.primitives:
            d = "—" if p.row is None else f"({p.row - n.row}, {p.col - n.col})"
            num = ["—" if v is None else f"{v:.2f}" for v in (p.cost, p.g, p.f)]
            rows.append(f"| {i} | ({n.x:.1f}, {n.y:.1f}), {n.g:.2f} | {PRIMITIVES[p.primitive]} "
                        f"| {d} | {'—' if p.layer is None else p.layer} | {' | '.join(num)} "
                        f"| {p.outcome} |")
    return "\n".join(rows)
