"""Motion primitives and the paper's directional cost model.

Three forward arc primitives — straight, left and right at the minimum turning
radius r_min — each of arc length s = ``step_m`` (paper: s = 1.6 m). A move
from cell (i, j) to cell (i', j') is priced in the costmap layer k* nearest to
its travel direction (Directional Cost Lookup), the cost C ∈ [0, 1] there is
amplified to C' = C(1 + βC), and the edge costs g_edge = s(1 + C').

Grid convention (docs/ARCHITECTURE.md): rows grow with y and columns with x, so the
paper's θ' = atan2(j' − j, i' − i) reads θ' = atan2(Δrow, Δcol) here.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from dgt_lib.core.geometry import TWO_PI, nearest_heading_bin, wrap_angle

# heading change of each primitive, in units of Δθ = s / r_min: straight, left, right
TURN_STEPS: tuple[int, ...] = (0, 1, -1)


def distance(dx: float, dy: float) -> float:
    """√(dx² + dy²) [m], the search's one formula for a distance between two points: plain
    IEEE operations, which the compiled search (:mod:`.compiled`) reproduces bit for bit
    (``math.hypot`` rounds differently from the C library's ``hypot`` that numba calls)."""
    return math.sqrt(dx * dx + dy * dy)


def travel_heading_bin(d_row, d_col, n_headings: int):
    """Directional cost layer for a move of (Δrow, Δcol) grid cells.

    Paper (Directional Cost Lookup): θ' = atan2(j' − j, i' − i) and
    k* = argmin_k |θ_k − θ'|. With rows along y and columns along x (docs/ARCHITECTURE.md)
    the world travel direction is θ' = atan2(Δrow, Δcol), so Δcol > 0 gives
    k* = 0 and Δrow > 0 gives k* = K/4. Integers or arrays; (0, 0) has no
    direction and gives k* = 0 (callers fall back to the motion's heading).
    """
    theta = np.arctan2(np.asarray(d_row, dtype=np.float64), np.asarray(d_col, dtype=np.float64))
    return nearest_heading_bin(theta, n_headings)


def amplified_cost(cost, beta: float):
    """C' = C(1 + βC) (paper eq. stretch): super-linear penalty of cost C ∈ [0, 1]."""
    return cost * (1.0 + beta * cost)


def edge_cost(length_m: float, amplified: float) -> float:
    """g_edge = s(1 + C') [m] (paper eq. edge_cost) for a move of length s = ``length_m``."""
    return length_m * (1.0 + amplified)


def step_cost(length_m: float, cost: float, beta: float) -> float:
    """g_edge = s(1 + C(1 + βC)) [m]: :func:`edge_cost` of the :func:`amplified_cost` of a
    move of length s = ``length_m`` over looked-up cost C = ``cost`` (the planner's default
    edge cost; a function of the same signature can replace it, see ``HybridAStar``)."""
    return edge_cost(length_m, amplified_cost(cost, beta))


def travel_bin_table(step_m: float, resolution: float, n_headings: int) -> tuple[list[int], int]:
    """k* of :func:`travel_heading_bin` for every (Δrow, Δcol) one primitive can produce.

    Returns (table, reach): a flat list indexed by
    (Δrow + reach)·(2·reach + 1) + (Δcol + reach), with −1 at (0, 0), where the
    move has no cell direction and the motion's own heading is used instead.
    """
    reach = math.ceil(step_m / resolution) + 2
    d = np.arange(-reach, reach + 1)
    table = travel_heading_bin(d[:, None], d[None, :], n_headings)
    table[reach, reach] = -1  # no cell change: use the motion's heading instead
    return table.ravel().tolist(), reach


def arc_poses(pose, curvature: float, arc_lengths) -> np.ndarray:
    """Poses (N, 3) reached from ``pose`` (x, y, θ) along an arc of signed curvature
    κ [1/m] (left > 0) after ``arc_lengths`` (N,) [m]; θ is not wrapped."""
    x, y, th = (float(v) for v in pose)
    t = np.asarray(arc_lengths, dtype=np.float64)
    if curvature == 0.0:
        return np.stack([x + t * math.cos(th), y + t * math.sin(th), np.full_like(t, th)], axis=1)
    th_t = th + curvature * t
    return np.stack(
        [
            x + (np.sin(th_t) - math.sin(th)) / curvature,
            y - (np.cos(th_t) - math.cos(th)) / curvature,
            th_t,
        ],
        axis=1,
    )


class TurnTable(NamedTuple):
    """The three primitives from any pose of heading θ = θ_start + n·Δθ, relative to it.

    cells: (3, 3·n_sub·n_circles) footprint-circle centres of all sub-steps,
        (row, col) offsets in cells, primitive-major, then a row of zeros (the
        homogeneous coordinate of ``BlockedMap.primitive_hits``).
    ends: per primitive, the (Δx, Δy) [m] of its end pose.
    closed_bins: per primitive, the closed-set heading bin of its end pose.
    fallback_layers: per primitive, the cost layer of its mid-arc heading, used
        when the move stays in one cell.
    """

    cells: np.ndarray
    ends: tuple[tuple[float, float], ...]
    closed_bins: tuple[int, ...]
    fallback_layers: tuple[int, ...]


class Successor(NamedTuple):
    """Where one primitive ends and the costmap layer its move is priced in: end position
    (x, y) [m], its cell (row, col), and k* = ``layer`` (:func:`travel_heading_bin` of the
    cell move from the parent's cell, or of the mid-arc heading when the cell is kept)."""

    x: float
    y: float
    row: int
    col: int
    layer: int


class PrimitiveSet:
    """The arc primitives of one query: headings θ_start + n·Δθ (Δθ = s / r_min) are
    indexed by the turn count n, and the primitives' sub-step geometry is tabulated
    once per n (:meth:`table`). ``origin_xy`` [m]: the grid's origin, for the cells of
    :meth:`successor`."""

    def __init__(self, start_heading: float, *, step_m: float, min_turn_radius_m: float,
                 substep_m: float, circle_offsets: np.ndarray, resolution: float,
                 theta_bins: int, n_headings: int, origin_xy: tuple[float, float] = (0.0, 0.0)):
        self.start_heading = start_heading
        self.origin_xy = (float(origin_xy[0]), float(origin_xy[1]))
        # k* of every cell move one primitive can make (travel_heading_bin, tabulated)
        self.layer_table, self.reach = travel_bin_table(step_m, resolution, n_headings)
        self.curvatures = (0.0, 1.0 / min_turn_radius_m, -1.0 / min_turn_radius_m)
        self.dtheta = step_m / min_turn_radius_m
        n_sub = math.ceil(step_m / substep_m)
        self.sub_t = step_m * np.arange(1, n_sub + 1) / n_sub  # arc length of each sub-step
        self.circle_offsets = circle_offsets
        self.inv_res = 1.0 / resolution
        self.theta_bins = theta_bins
        self.n_headings = n_headings
        self.tables: dict[int, TurnTable] = {}

    def heading(self, n: int) -> float:
        """θ = θ_start + n·Δθ [rad] (not wrapped)."""
        return self.start_heading + n * self.dtheta

    def table(self, n: int) -> TurnTable:
        """The :class:`TurnTable` of turn count n (cached)."""
        entry = self.tables.get(n)
        if entry is None:
            entry = self.tables[n] = self._build(n)
        return entry

    def _build(self, n: int) -> TurnTable:
        th = self.start_heading + n * self.dtheta
        offsets, dtheta = self.circle_offsets, self.dtheta
        cx, cy, ends = [], [], []
        for kappa in self.curvatures:
            poses = arc_poses((0.0, 0.0, th), kappa, self.sub_t)
            cx.append(poses[:, :1] + offsets * np.cos(poses[:, 2:]))
            cy.append(poses[:, 1:2] + offsets * np.sin(poses[:, 2:]))
            ends.append((float(poses[-1, 0]), float(poses[-1, 1])))
        cells = np.stack([np.concatenate(cy).ravel(), np.concatenate(cx).ravel()]) * self.inv_res
        cells = np.vstack([cells, np.zeros((1, cells.shape[1]))])
        bin_width = TWO_PI / self.theta_bins
        closed_bins = tuple(
            int(math.floor(wrap_angle(th + dn * dtheta) / bin_width + 0.5)) % self.theta_bins
            for dn in TURN_STEPS
        )
        fallback = tuple(
            int(nearest_heading_bin(th + dn * dtheta / 2, self.n_headings)) for dn in TURN_STEPS
        )
        return TurnTable(cells, tuple(ends), closed_bins, fallback)

    def poses(self, x: float, y: float, n: int, primitive: int) -> np.ndarray:
        """Sub-step poses (n_sub, 3) of ``primitive`` from (x, y, θ_start + n·Δθ)."""
        return arc_poses((x, y, self.heading(n)), self.curvatures[primitive], self.sub_t)

    def move_layer(self, d_row: int, d_col: int) -> int | None:
        """k* = :func:`travel_heading_bin` of a cell move (Δrow, Δcol) one primitive can
        make (from a table), None for (0, 0): a move within one cell has no direction."""
        k = self.layer_table[(d_row + self.reach) * (2 * self.reach + 1) + d_col + self.reach]
        return None if k < 0 else k

    def successor(self, x: float, y: float, n: int, row: int, col: int,
                  primitive: int) -> Successor:
        """The end of ``primitive`` (0 straight, 1 left, 2 right) from the pose (x, y,
        θ_start + n·Δθ) in cell (row, col), and the layer k* its move reads: that of the
        cell move, or, when the cell is kept, that of the arc's mid heading."""
        table = self.table(n)
        dx, dy = table.ends[primitive]
        x_end, y_end = x + dx, y + dy
        x0, y0 = self.origin_xy
        row_end, col_end = int((y_end - y0) * self.inv_res), int((x_end - x0) * self.inv_res)
        layer = self.move_layer(row_end - row, col_end - col)
        if layer is None:
            layer = table.fallback_layers[primitive]
        return Successor(x_end, y_end, row_end, col_end, layer)
