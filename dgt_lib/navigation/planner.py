"""Direction-aware Hybrid A* (paper: Traversability-Aware Path Planning).

The planner searches over continuous poses (x, y, θ) [m, m, rad] with three
forward arc primitives — straight, left and right at the vehicle's minimum
turning radius r_min — each of arc length s = ``step_m`` (paper: s = 1.6 m).
Two decoupled map layers drive it:

- the occupancy map ``(H, W)`` uint8 (0 free, 1 occupied, 2 unobserved, the
  last treated as occupied) rejects primitives that collide, checked at fine
  sub-steps along each arc with the vehicle's footprint;
- the directional costmap ``(K, H, W)`` in [0, 1] (layer k is heading
  θ_k = 2πk/K) prices each primitive at its successor cell, in the layer
  nearest to the travel direction, amplified by β (paper: β = 150).

Conventions (DESIGN.md): rows grow with y, θ is counter-clockwise from +x. The
paper writes the travel direction as atan2(j' − j, i' − i) on grid indices; in
our grid the row index follows y and the column index follows x, so the same
direction in world terms is θ' = atan2(Δrow, Δcol) — travel toward +x reads
layer 0 and travel toward +y reads layer K/4.

Usage::

    planner = HybridAStar(costmap, occupancy, grid, min_turn_radius_m=5.7,
                          footprint=(6.4, 2.4), cfg=profile.planner)
    result = planner.plan((10.0, 20.0, 0.0), (120.0, 90.0))
    result.path            # (N, 3) x, y, θ at sub-step spacing
    result.cost            # Σ g_edge

:func:`plan` is the one-call form. A :class:`HybridAStar` keeps what depends
only on the map (footprint dilation, the 2D cost field) and the cost-to-go of
recent goals, so repeated queries on one map are cheaper.

Footprint approximation: the vehicle rectangle (length × width, centred on the
pose) is covered by an odd number n ≥ length/width of equal circles on its
long axis (:func:`footprint_circles`). A circle centre is snapped to its cell,
and the cell is blocked when an occupied or unobserved cell centre lies closer
than r_circle + ``safety_margin_m`` + res·√2/2. Hence at every checked sub-step
no occupied cell centre lies inside any footprint circle, hence none inside the
vehicle rectangle; the price is up to ~res·√2 of extra clearance.

Search: A* with f = g + w·h over the nodes' exact poses; a closed set over
(x, y, θ) cells of ``closed_cell_m`` × ``closed_cell_m`` × 360°/``theta_bins``
keeps the first node expanded in each cell (Hybrid A*'s state merging, the one
source of sub-optimality besides the weight w = ``heuristic_weight``). The
headings reachable from the start are θ_start + n·s/r_min, so the sub-step
offsets of the three arcs are tabulated once per turn count n and each
expansion checks all of them with one vectorised lookup. Heuristics:
``"euclidean"`` (the paper's: distance to the goal point) or ``"cost_to_go"``
(its max with a direction-aware 2D lower bound, :meth:`HybridAStar.cost_to_go`,
which also refutes unreachable goals before the search starts).

Deterministic: ties in the open list break by insertion order; no randomness.
"""

from __future__ import annotations

import heapq
import math
import time
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import TWO_PI, GridSpec, angle_diff, nearest_heading_bin, wrap_angle
from dgt_lib.core.vehicles import VehicleSpec, footprint_circles, get_vehicle

HEURISTICS: tuple[str, ...] = ("euclidean", "cost_to_go")

_SHOT = 3  # primitive index of an analytic shot node


class InvalidQueryError(ValueError):
    """A start or goal that cannot be planned for (off the map, in an obstacle)."""


@dataclass(frozen=True)
class PlanResult:
    """The outcome of one query.

    path: (N, 3) poses x [m], y [m], θ [rad, in [0, 2π)] from start to goal at
        sub-step spacing (≤ ``substep_m``); shape (0, 3) when ``success`` is False.
    cost: Σ g_edge of the path (∞ on failure).
    expansions: nodes taken from the open list and expanded.
    time_s: wall time of the query, including the heuristic's set-up.
    success: whether the goal was reached.
    reason: "reached goal" or why not (starts with "no path").
    nodes: (M, 3) the search nodes on the path (primitive end poses; the goal
        pose when an analytic shot finished it).
    node_costs: (M,) cost-so-far g at each node (node_costs[-1] == cost).
    expanded_xy: (E, 2) positions of all expanded nodes, in expansion order.
    """

    path: np.ndarray
    cost: float
    expansions: int
    time_s: float
    success: bool
    reason: str
    nodes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    node_costs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    expanded_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def length_m(self) -> float:
        """Length of the path polyline [m] (0 on failure)."""
        if len(self.path) < 2:
            return 0.0
        return float(np.hypot(*np.diff(self.path[:, :2], axis=0).T).sum())


# --- the paper's cost model ---------------------------------------------------------------


def travel_heading_bin(d_row, d_col, n_headings: int):
    """Directional cost layer for a move of (Δrow, Δcol) grid cells.

    Paper (Directional Cost Lookup): θ' = atan2(j' − j, i' − i) and
    k* = argmin_k |θ_k − θ'|. With rows along y and columns along x (DESIGN.md)
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


# --- geometry helpers --------------------------------------------------------------------




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


def sample_segments(pose, segments, radius: float, spacing_m: float) -> np.ndarray:
    """Poses (N, 3) along consecutive (kind, length [m]) segments, kind ∈ {"L", "S", "R"},
    at most ``spacing_m`` apart, the start pose excluded and the end pose included."""
    out = []
    current = np.asarray(pose, dtype=np.float64)
    for kind, length in segments:
        if length <= 1e-12:
            continue
        n = max(1, math.ceil(length / spacing_m))
        kappa = {"L": 1.0 / radius, "S": 0.0, "R": -1.0 / radius}[kind]
        poses = arc_poses(current, kappa, length * np.arange(1, n + 1) / n)
        out.append(poses)
        current = poses[-1]
    return np.concatenate(out) if out else np.zeros((0, 3))


def _mod2pi(a: float) -> float:
    return a - TWO_PI * math.floor(a / TWO_PI)


def dubins_path(start, goal, radius: float) -> list[tuple[str, float]]:
    """Shortest Dubins path (forward, curvature ≤ 1/radius) between two poses.

    start, goal: (x, y, θ) [m, m, rad]. Returns three (kind, length [m]) segments,
    kind ∈ {"L", "S", "R"}, of the shortest of the six words LSL, RSR, LSR, RSL,
    RLR, LRL (Dubins 1957; formulas in the frame where the start is at the
    origin and the goal on the +x axis, distances in units of the radius).
    """
    dx, dy = goal[0] - start[0], goal[1] - start[1]
    d = math.hypot(dx, dy) / radius
    phi = math.atan2(dy, dx)
    a, b = _mod2pi(start[2] - phi), _mod2pi(goal[2] - phi)
    sa, sb, ca, cb, cab = math.sin(a), math.sin(b), math.cos(a), math.cos(b), math.cos(a - b)
    words: list[tuple[str, tuple[float, float, float]]] = []
    p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)  # LSL
    if p2 >= 0:
        tmp = math.atan2(cb - ca, d + sa - sb)
        words.append(("LSL", (_mod2pi(-a + tmp), math.sqrt(p2), _mod2pi(b - tmp))))
    p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)  # RSR
    if p2 >= 0:
        tmp = math.atan2(ca - cb, d - sa + sb)
        words.append(("RSR", (_mod2pi(a - tmp), math.sqrt(p2), _mod2pi(-b + tmp))))
    p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)  # LSR
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        words.append(("LSR", (_mod2pi(-a + tmp), p, _mod2pi(-b + tmp))))
    p2 = -2 + d * d + 2 * cab - 2 * d * (sa + sb)  # RSL
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        words.append(("RSL", (_mod2pi(a - tmp), p, _mod2pi(b - tmp))))
    c = (6 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8  # RLR
    if abs(c) <= 1:
        p = _mod2pi(TWO_PI - math.acos(c))
        t = _mod2pi(a - math.atan2(ca - cb, d - sa + sb) + p / 2)
        words.append(("RLR", (t, p, _mod2pi(a - b - t + p))))
    c = (6 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8  # LRL
    if abs(c) <= 1:
        p = _mod2pi(TWO_PI - math.acos(c))
        t = _mod2pi(-a - math.atan2(ca - cb, d + sa - sb) + p / 2)
        words.append(("LRL", (t, p, _mod2pi(b - a - t + p))))
    word, lengths = min(words, key=lambda w: sum(w[1]))
    return [(kind, length * radius) for kind, length in zip(word, lengths, strict=True)]


def turn_then_straight(start, goal_xy, radius: float) -> list[tuple[str, float]] | None:
    """Shortest CS path (one minimum-radius turn, then straight) from a pose to a point.

    The final heading is free. Returns two (kind, length [m]) segments, or None
    when the point lies inside both turning circles (no CS path exists).
    """
    x, y, th = start
    best = None
    for kind, side in (("L", 1.0), ("R", -1.0)):
        cx, cy = x - side * radius * math.sin(th), y + side * radius * math.cos(th)
        dist = math.hypot(goal_xy[0] - cx, goal_xy[1] - cy)
        if dist < radius:
            continue
        straight = math.sqrt(max(dist * dist - radius * radius, 0.0))
        # polar angle ψ (about the centre) of the tangent point, and of the start
        phi = math.atan2(goal_xy[1] - cy, goal_xy[0] - cx)
        psi = phi - side * math.atan2(straight, radius)
        psi0 = th - side * math.pi / 2
        turn = _mod2pi(side * (psi - psi0))
        if best is None or turn * radius + straight < best[0]:
            best = (turn * radius + straight, [(kind, turn * radius), ("S", straight)])
    return None if best is None else best[1]


def step_cell_bounds(step_m: float, resolution: float) -> tuple[float, float]:
    """Largest (octile length, Euclidean length) [m] between the cell centres of two
    points at most ``step_m`` apart on a grid of ``resolution``.

    A displacement of (a, b) cells needs |Δx| > (a − 1)·res and |Δy| > (b − 1)·res,
    so the candidates are the integers with max(a−1, 0)² + max(b−1, 0)² < (s/res)²;
    the octile length of (a, b) is (max + (√2 − 1)·min)·res.
    """
    q = step_m / resolution
    n = math.ceil(q) + 1
    best_octile = best_dist = 0.0
    for a in range(n + 1):
        for b in range(a + 1):
            if max(a - 1, 0) ** 2 + max(b - 1, 0) ** 2 < q * q:
                best_octile = max(best_octile, a + (math.sqrt(2) - 1) * b)
                best_dist = max(best_dist, math.hypot(a, b))
    return best_octile * resolution, best_dist * resolution


# --- the planner ---------------------------------------------------------------------------


class HybridAStar:
    """Hybrid A* on one costmap + occupancy map for one vehicle.

    costmap: (K, H, W) float in [0, 1], layer k = heading 2πk/K (a (H, W) array
        is taken as K = 1, i.e. isotropic; zeros give a binary planner).
    occupancy: (H, W) uint8, 0 free, 1 occupied, 2 unobserved (= occupied).
    grid: the :class:`GridSpec` of both arrays.
    min_turn_radius_m: r_min [m] of the arc primitives.
    footprint: (length_m, width_m) of the vehicle rectangle centred on the pose.
    cfg: :class:`PlannerConfig` (step_m, beta, heuristic, tolerances, caps, ...).
    """

    def __init__(
        self,
        costmap: np.ndarray,
        occupancy: np.ndarray,
        grid: GridSpec,
        *,
        min_turn_radius_m: float,
        footprint: tuple[float, float],
        cfg: PlannerConfig | None = None,
    ):
        cfg = PlannerConfig() if cfg is None else cfg
        _check_config(cfg)
        costmap = np.asarray(costmap)
        if costmap.ndim == 2:
            costmap = costmap[None]
        if costmap.ndim != 3 or costmap.shape[1:] != grid.shape:
            raise ValueError(
                f"costmap must be (K, H, W) with (H, W) = {grid.shape}, got {costmap.shape}"
            )
        if not np.all(np.isfinite(costmap)) or costmap.min() < 0 or costmap.max() > 1:
            raise ValueError("costmap values must be finite and in [0, 1]")
        occupancy = np.asarray(occupancy)
        if occupancy.shape != grid.shape:
            raise ValueError(f"occupancy must be (H, W) = {grid.shape}, got {occupancy.shape}")
        if not np.isin(occupancy, (0, 1, 2)).all():
            raise ValueError("occupancy values must be 0 (free), 1 (occupied) or 2 (unobserved)")
        if not min_turn_radius_m > 0:
            raise ValueError(f"min_turn_radius_m must be > 0, got {min_turn_radius_m}")

        self.cfg = cfg
        self.grid = grid
        self.n_headings = costmap.shape[0]
        self.min_turn_radius_m = float(min_turn_radius_m)
        self.footprint = (float(footprint[0]), float(footprint[1]))
        self.circle_offsets, self.circle_radius_m = footprint_circles(*self.footprint)
        self._costmap = np.ascontiguousarray(costmap, dtype=np.float64)
        self._cost_flat = self._costmap.ravel()

        res = grid.resolution
        H, W = grid.shape
        # distance [m] from every cell centre to the nearest occupied/unobserved cell centre
        self._occupied_distance = ndimage.distance_transform_edt(occupancy == 0) * res
        self.clearance_m = self.circle_radius_m + cfg.safety_margin_m + res * math.sqrt(2) / 2
        blocked = self._occupied_distance < self.clearance_m
        self.blocked = blocked
        padded = np.ones((H + 2, W + 2), dtype=bool)  # a blocked border catches off-map points
        padded[1:-1, 1:-1] = blocked
        self._blocked_flat = padded.ravel()

        # nearest-bin table of k* for every (Δrow, Δcol) one primitive can produce
        reach = math.ceil(cfg.step_m / res) + 2
        d = np.arange(-reach, reach + 1)
        table = travel_heading_bin(d[:, None], d[None, :], self.n_headings)
        table[reach, reach] = -1  # no cell change: use the motion's heading instead
        self._bin_reach = reach
        self._bin_table = table.ravel().tolist()

        self._graphs: tuple[csr_matrix, csr_matrix] | None = None
        self._cost_to_go_cache: OrderedDict = OrderedDict()

    # --- collision -------------------------------------------------------------------------


    @classmethod
    def for_vehicle(cls, costmap: np.ndarray, occupancy: np.ndarray, grid: GridSpec,
                    vehicle: str | VehicleSpec, cfg: PlannerConfig | None = None
                    ) -> HybridAStar:
        """The planner of one vehicle: its centre turning radius and its footprint
        (length × width) from :mod:`dgt_lib.core.vehicles`."""
        spec = get_vehicle(vehicle)
        return cls(costmap, occupancy, grid, min_turn_radius_m=spec.centre_turn_radius_m,
                   footprint=(spec.length_m, spec.width_m), cfg=cfg)
    def _circle_index(self, x, y, theta) -> np.ndarray:
        """Flat indices into the padded blocked map of all footprint circles at poses."""
        res = self.grid.resolution
        x0, y0 = self.grid.origin_xy
        H, W = self.grid.shape
        off = self.circle_offsets
        cx = np.asarray(x)[..., None] + off * np.cos(np.asarray(theta))[..., None]
        cy = np.asarray(y)[..., None] + off * np.sin(np.asarray(theta))[..., None]
        col = np.floor((cx - x0) / res).astype(np.int64) + 1
        row = np.floor((cy - y0) / res).astype(np.int64) + 1
        return np.ravel_multi_index((row, col), (H + 2, W + 2), mode="clip")

    def collides(self, poses: np.ndarray) -> np.ndarray:
        """(N,) bool: whether the footprint at each pose (N, 3) hits an occupied or
        unobserved cell or leaves the map (the footprint-circle check above)."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        idx = self._circle_index(poses[:, 0], poses[:, 1], poses[:, 2])
        return self._blocked_flat[idx].any(axis=1)

    # --- heuristic -------------------------------------------------------------------------

    def cost_to_go(self, goal_xy) -> np.ndarray:
        """(H, W) admissible lower bound [cost units, i.e. metres of g_edge] of the cost
        from any pose in a cell to the goal region (∞ where the goal is unreachable).

        Two direction-aware 2D relaxations on the 8-connected grid, solved once per
        goal with ``scipy.sparse.csgraph.dijkstra``: D prices a grid move m
        (direction ψ_m = m·45°, length ℓ_m = res or √2·res) into cell c at
        ℓ_m·(1 + min_{k ∈ S_m} F_k(c)), and D_c at ℓ_m·min_{k ∈ S_m} F_k(c)
        (the terrain part alone), where F_k = min of C'_k = C_k(1 + βC_k) over the
        unblocked cells (those a footprint centre may occupy) within ρ of c, and
        S_m = the layers within 45° + 180°/K of ψ_m. Let O
        and E be the largest octile and Euclidean distances between the cells of
        two points ≤ s apart (:func:`step_cell_bounds`; s = 1.6 m, res = 0.4 m: a
        (4, 3)-cell jump, O = 2.10 m, E = 2.0 m); ρ = E + res/2. Cells whose
        centre is closer than clearance − (res/2 + √2·res + σ + Δ/2) to an
        occupied centre are impassable (σ = s²/(8 r_min) the arc's sagitta, Δ the
        sub-step spacing); sources are free cells within tol + res·√2/2 of the
        goal. With φ = s/O (0.76 at s = 1.6 m, res = 0.4 m) the bound is

            h = max(φ·D, max(d − tol, 0) + φ·D_c),

        d the distance from the pose to the goal point (here the cell's nearest
        point to it). During the search d is the pose's own distance and the
        "− tol" is dropped, as in the paper's Euclidean heuristic: that
        overestimates by at most tol, so the search returns a cost within
        ``goal_tolerance_m`` (× ``heuristic_weight``) of the optimum of its graph.

        Why it is a lower bound. Take any collision-free primitive path p_0..p_n
        ending within tol of the goal, with cells a_i ∋ p_i (centres c_i); an arc
        of length s has a chord ≤ s. Join c_{i−1} to c_i by a digital straight
        line (Bresenham): its moves are the one or two 45°-multiples bracketing the
        direction of c_i − c_{i−1}, whose nearest layer k* (the one the step pays)
        is therefore in S_m of every move; its length is the octile length ≤ O;
        its cells lie within res/2 of the segment c_{i−1}c_i, hence within ρ of
        c_i, an unblocked cell, so each move costs ≤ ℓ_m(1 + C'_i) and the line ≤ O(1 + C'_i) =
        g_edge,i/φ (for D_c: ≤ O·C'_i = s·C'_i/φ). Those cells also lie within
        res/2 + √2·res + σ + Δ/2 of a checked sub-step's cell centre, which is
        ≥ clearance from occupied centres, so they are passable; a_n is a
        source. Summing, φ·D(a_0) ≤ J = Σ s(1 + C'_i) and φ·D_c(a_0) ≤ Σ s·C'_i,
        while Σ s ≥ |p_0 − p_n| ≥ d − tol. Each part is consistent on every edge,
        hence so is the max. The analytic shot's last piece, shorter than s, is
        the one place the per-step argument is loose.
        """
        h_full, h_terrain = self._bounds(goal_xy)
        X, Y = self.grid.cell_centers()
        half_diagonal = self.grid.resolution * math.sqrt(2) / 2
        d = np.hypot(X - float(goal_xy[0]), Y - float(goal_xy[1])) - half_diagonal
        return np.maximum(h_full, np.maximum(d - self.cfg.goal_tolerance_m, 0.0) + h_terrain)

    def _bounds(self, goal_xy, as_lists: bool = False) -> tuple:
        """(φ·D, φ·D_c), each (H, W), of :meth:`cost_to_go` for one goal (cached); with
        ``as_lists`` flat Python lists (fast scalar lookups in the search loop)."""
        gx, gy = float(goal_xy[0]), float(goal_xy[1])
        key = (gx, gy)
        if key in self._cost_to_go_cache:
            self._cost_to_go_cache.move_to_end(key)
            return self._cost_to_go_cache[key][1 if as_lists else 0]
        res = self.grid.resolution
        if self._graphs is None:
            self._graphs = self._relaxation_graphs()
        X, Y = self.grid.cell_centers()
        source = np.hypot(X - gx, Y - gy) <= self.cfg.goal_tolerance_m + res * math.sqrt(2) / 2
        source = np.flatnonzero(source & ~self._impassable)
        phi = self.cfg.step_m / step_cell_bounds(self.cfg.step_m, res)[0]
        bounds = []
        for graph in self._graphs:
            if len(source) == 0:
                dist = np.full(self.grid.shape, np.inf)
            else:
                dist = dijkstra(graph, directed=True, indices=source, min_only=True)
            bounds.append(phi * dist.reshape(self.grid.shape))
        bounds = tuple(bounds)
        lists = tuple(b.ravel().tolist() for b in bounds)
        self._cost_to_go_cache[key] = (bounds, lists)
        while len(self._cost_to_go_cache) > 4:
            self._cost_to_go_cache.popitem(last=False)
        return lists if as_lists else bounds

    def _relaxation_graphs(self) -> tuple[csr_matrix, csr_matrix]:
        """The reversed 8-connected graphs of :meth:`cost_to_go` (edge v → u carries the
        cost of the move u → v), for D and D_c, as CSR matrices over flat cell indices."""
        cfg, res = self.cfg, self.grid.resolution
        H, W = self.grid.shape
        s = cfg.step_m
        rho = (step_cell_bounds(s, res)[1] + res / 2) / res  # [cells]
        half = math.floor(rho)
        d = np.arange(-half, half + 1)
        disk = np.hypot(d[:, None], d[None, :]) <= rho
        # F_k: min of C'_k over the unblocked cells within ρ (a pose's cell is unblocked)
        least = np.stack([
            ndimage.minimum_filter(np.where(self.blocked, np.inf, amplified_cost(layer, cfg.beta)),
                                   footprint=disk, mode="constant", cval=np.inf)
            for layer in self._costmap
        ])
        sagitta = s * s / (8 * self.min_turn_radius_m)
        slack = res / 2 + math.sqrt(2) * res + sagitta + self._substep() / 2
        self._impassable = self._occupied_distance < self.clearance_m - slack
        passable = ~self._impassable
        theta_k = TWO_PI * np.arange(self.n_headings) / self.n_headings
        index = np.arange(H * W).reshape(H, W)
        rows, cols, terrain, lengths = [], [], [], []
        for m in range(8):
            psi = m * math.pi / 4
            dr, dc = round(math.sin(psi)), round(math.cos(psi))
            spread = math.pi / 4 + math.pi / self.n_headings + 1e-9
            near = np.abs(angle_diff(theta_k, psi)) <= spread
            length = res * math.hypot(dr, dc)
            # moves u -> v = u + (dr, dc) with both cells passable, charged at v
            u = (slice(max(0, -dr), H - max(0, dr)), slice(max(0, -dc), W - max(0, dc)))
            v = (slice(max(0, dr), H - max(0, -dr)), slice(max(0, dc), W - max(0, -dc)))
            ok = passable[u] & passable[v] & np.isfinite(least[near].min(axis=0)[v])
            rows.append(index[v][ok])
            cols.append(index[u][ok])
            terrain.append(length * least[near].min(axis=0)[v][ok])
            lengths.append(np.full(int(ok.sum()), length))
        index_pairs = (np.concatenate(rows), np.concatenate(cols))
        terrain, lengths = np.concatenate(terrain), np.concatenate(lengths)
        shape = (H * W, H * W)
        return (csr_matrix((lengths + terrain, index_pairs), shape=shape),
                csr_matrix((terrain, index_pairs), shape=shape))

    def _substep(self) -> float:
        """Actual sub-step spacing Δ [m] along a primitive (≤ cfg.substep_m)."""
        return self.cfg.step_m / math.ceil(self.cfg.step_m / self.cfg.substep_m)

    # --- query -------------------------------------------------------------------------------

    def _check_query(self, start, goal) -> tuple[float, float, float, float, float, float | None]:
        start = np.asarray(start, dtype=np.float64).ravel()
        goal = np.asarray(goal, dtype=np.float64).ravel()
        if start.shape != (3,) or not np.all(np.isfinite(start)):
            raise InvalidQueryError(f"start must be a finite (x, y, θ), got {start.tolist()}")
        if goal.shape not in ((2,), (3,)) or not np.all(np.isfinite(goal)):
            raise InvalidQueryError(
                f"goal must be a finite (x, y) or (x, y, θ), got {goal.tolist()}"
            )
        sx, sy, sth = start
        gx, gy = goal[:2]
        gth = float(goal[2]) if goal.shape == (3,) else None
        for name, (x, y) in (("start", (sx, sy)), ("goal", (gx, gy))):
            if not self.grid.contains(x, y):
                raise InvalidQueryError(
                    f"{name} ({x:.2f}, {y:.2f}) m is off the map (extent {self.grid.extent})"
                )
        if self.collides(start)[0]:
            raise InvalidQueryError(
                f"start pose ({sx:.2f}, {sy:.2f}, {sth:.2f}) is in an obstacle: the "
                f"{self.footprint[0]:.2f}×{self.footprint[1]:.2f} m footprint hits an occupied "
                "or unobserved cell (or the map edge)"
            )
        r, c = self.grid.xy_to_cell(gx, gy)
        if self._occupied_distance[r, c] == 0:
            raise InvalidQueryError(
                f"goal ({gx:.2f}, {gy:.2f}) is in an occupied or unobserved cell"
            )
        if gth is not None and self.collides((gx, gy, gth))[0]:
            raise InvalidQueryError(
                f"goal pose ({gx:.2f}, {gy:.2f}, {gth:.2f}) is in an obstacle: the footprint "
                "hits an occupied or unobserved cell (or the map edge)"
            )
        return float(sx), float(sy), float(wrap_angle(sth)), float(gx), float(gy), gth

    def _shot(self, pose, gx: float, gy: float, gth: float | None, max_length_m: float):
        """Poses (N, 3) of a collision-free analytic shot from ``pose`` to the goal, or
        None (also when the shot is not shorter than ``max_length_m``)."""
        r = self.min_turn_radius_m
        if gth is None:
            segments = turn_then_straight(pose, (gx, gy), r)
            if segments is None:
                return None
        else:
            segments = dubins_path(pose, (gx, gy, gth), r)
        if sum(length for _, length in segments) >= max_length_m:
            return None
        poses = sample_segments(pose, segments, r, self._substep())
        if len(poses) == 0 or self.collides(poses).any():
            return None
        return poses

    def _shot_cost(self, pose, poses: np.ndarray) -> float:
        """Σ g_edge along a shot, priced like primitives: pieces of arc length s (the last
        one shorter, priced by its length), each at its end cell's directional cost."""
        s, beta = self.cfg.step_m, self.cfg.beta
        seg = np.hypot(*np.diff(np.vstack([np.asarray(pose)[None, :3], poses])[:, :2], axis=0).T)
        arc = np.cumsum(seg)
        total_len = float(arc[-1])
        n_pieces = max(1, math.ceil(total_len / s - 1e-9))
        ends = np.minimum(np.arange(1, n_pieces + 1) * s, total_len)
        idx = np.minimum(np.searchsorted(arc, ends - 1e-9), len(poses) - 1)
        pts = np.vstack([np.asarray(pose)[None, :3], poses[idx]])
        rows, cols = self.grid.xy_to_cell(pts[:, 0], pts[:, 1])
        lengths = np.diff(np.concatenate([[0.0], ends]))
        H, W = self.grid.shape
        total = 0.0
        for i in range(n_pieces):
            dr, dc = int(rows[i + 1] - rows[i]), int(cols[i + 1] - cols[i])
            if dr == 0 and dc == 0:
                k = int(nearest_heading_bin(pts[i + 1, 2], self.n_headings))
            else:
                k = int(travel_heading_bin(dr, dc, self.n_headings))
            cost = self._cost_flat[(k * H + rows[i + 1]) * W + cols[i + 1]]
            total += edge_cost(float(lengths[i]), amplified_cost(float(cost), beta))
        return total

    def plan(self, start, goal) -> PlanResult:
        """Plan from ``start`` (x, y, θ) to ``goal`` (x, y) or (x, y, θ) [m, m, rad].

        The goal is reached when a node lies within ``goal_tolerance_m`` (and, if a
        goal heading is given, within ``goal_heading_tolerance_rad`` of it), or by an
        analytic shot (Dubins to a goal pose, turn-then-straight to a point) that is
        collision-free; a shot enters the open list as a goal candidate priced like
        primitives, so it is only taken when nothing cheaper is pending.

        Raises :class:`InvalidQueryError` for a start or goal off the map, a start
        pose whose footprint collides, a goal point in an occupied or unobserved
        cell, or a goal pose whose footprint collides. An unreachable goal returns
        ``success=False`` with a reason starting "no path", bounded by
        ``max_expansions`` and ``max_time_s``.
        """
        t0 = time.perf_counter()
        cfg = self.cfg
        sx, sy, sth, gx, gy, gth = self._check_query(start, goal)
        s, beta, tol = cfg.step_m, cfg.beta, cfg.goal_tolerance_m
        tol_heading = cfg.goal_heading_tolerance_rad
        res = self.grid.resolution
        x0, y0 = self.grid.origin_xy
        H, W = self.grid.shape
        K = self.n_headings
        inv_res = 1.0 / res

        h_grid = h_terrain = None
        if cfg.heuristic == "cost_to_go":
            h_grid, h_terrain = self._bounds((gx, gy), as_lists=True)

        def failure(reason: str, expansions: int, expanded) -> PlanResult:
            return PlanResult(
                path=np.zeros((0, 3)), cost=math.inf, expansions=expansions,
                time_s=time.perf_counter() - t0, success=False, reason=reason,
                expanded_xy=np.asarray(expanded, dtype=np.float64).reshape(-1, 2),
            )

        start_cell = self.grid.xy_to_cell(sx, sy)
        start_flat = int(start_cell[0]) * W + int(start_cell[1])
        if h_grid is not None and not math.isfinite(h_grid[start_flat]):
            return failure("no path: the goal is unreachable even in the 2D relaxation", 0, [])

        r_min = self.min_turn_radius_m
        curvatures = (0.0, 1.0 / r_min, -1.0 / r_min)
        turn_steps = (0, 1, -1)
        dtheta = s / r_min
        n_sub = math.ceil(s / cfg.substep_m)
        sub_t = s * np.arange(1, n_sub + 1) / n_sub
        offsets = self.circle_offsets
        theta_bin_width = TWO_PI / cfg.theta_bins
        cell = cfg.closed_cell_m
        nx_closed = math.ceil(W * res / cell) + 1
        blocked_flat = self._blocked_flat
        cost_flat = self._cost_flat
        bin_table, reach = self._bin_table, self._bin_reach
        bin_row = 2 * reach + 1

        tables: dict[int, tuple] = {}

        def table(n: int) -> tuple:
            """Per turn count n (θ = θ_start + n·Δθ): circle-centre offsets of all
            sub-steps of the three primitives scaled to cells, their end offsets,
            and the closed-set heading bins of the successors."""
            th = sth + n * dtheta
            cx, cy, ends = [], [], []
            for kappa in curvatures:
                poses = arc_poses((0.0, 0.0, th), kappa, sub_t)
                cx.append(poses[:, :1] + offsets * np.cos(poses[:, 2:]))
                cy.append(poses[:, 1:2] + offsets * np.sin(poses[:, 2:]))
                ends.append((float(poses[-1, 0]), float(poses[-1, 1])))
            cells = np.stack([np.concatenate(cy).ravel(), np.concatenate(cx).ravel()]) * inv_res
            bins = tuple(
                int(math.floor(wrap_angle(th + dn * dtheta) / theta_bin_width + 0.5))
                % cfg.theta_bins
                for dn in turn_steps
            )
            fallback = tuple(
                int(nearest_heading_bin(th + dn * dtheta / 2, K)) for dn in turn_steps
            )
            entry = (cells, ends, bins, fallback)
            tables[n] = entry
            return entry

        def closed_key(x: float, y: float, theta_bin: int) -> int:
            kx = int((x - x0) / cell)
            ky = int((y - y0) / cell)
            return (ky * nx_closed + kx) * cfg.theta_bins + theta_bin

        def is_goal(x: float, y: float, n: int) -> bool:
            if (x - gx) ** 2 + (y - gy) ** 2 > tol * tol:
                return False
            if gth is None:
                return True
            return abs(float(angle_diff(sth + n * dtheta, gth))) <= tol_heading

        # node storage (parallel lists): pose, turn count, cell, cost-so-far, parent, primitive
        X, Y, N = [sx], [sy], [0]
        R, C = [int(start_cell[0])], [int(start_cell[1])]
        G, parent, prim, goal_flag = [0.0], [-1], [-1], [is_goal(sx, sy, 0)]
        start_bin = int(math.floor(sth / theta_bin_width + 0.5)) % cfg.theta_bins
        KEY = [closed_key(sx, sy, start_bin)]
        shots: dict[int, np.ndarray] = {}
        h0 = math.hypot(sx - gx, sy - gy)
        if h_grid is not None:
            h0 = max(h_grid[start_flat], h0 + h_terrain[start_flat])
        weight = cfg.heuristic_weight
        open_list = [(weight * h0, 0, 0)]
        best_g = {KEY[0]: 0.0}
        closed: set[int] = set()
        expanded: list[tuple[float, float]] = []
        counter = 1
        best_goal = math.inf
        shot_range2 = cfg.shot_distance_m**2 if cfg.analytic_shot else -1.0
        offset_x, offset_y = (x0 - res) * inv_res, (y0 - res) * inv_res  # padded cells
        padded_shape = (H + 2, W + 2)
        shift = np.zeros((2, 1))  # the node's position in padded cells, per expansion
        n_bins = cfg.theta_bins
        max_expansions, max_time_s = cfg.max_expansions, cfg.max_time_s
        perf_counter, hypot = time.perf_counter, math.hypot
        heappop, heappush = heapq.heappop, heapq.heappush

        while open_list:
            if len(expanded) >= max_expansions:
                return failure(f"no path within max_expansions={max_expansions}",
                               len(expanded), expanded)
            if perf_counter() - t0 > max_time_s:
                return failure(f"no path within max_time_s={max_time_s}",
                               len(expanded), expanded)
            _, _, i = heappop(open_list)
            if goal_flag[i]:
                return self._result(i, X, Y, N, G, parent, prim, shots, curvatures, sub_t,
                                    sth, dtheta, len(expanded), expanded, t0)
            x, y, n, g = X[i], Y[i], N[i], G[i]
            key = KEY[i]
            if key in closed:
                continue
            closed.add(key)
            expanded.append((x, y))

            if (x - gx) ** 2 + (y - gy) ** 2 <= shot_range2:
                if g + math.hypot(x - gx, y - gy) < best_goal:
                    pose = (x, y, sth + n * dtheta)
                    poses = self._shot(pose, gx, gy, gth, best_goal - g)
                    if poses is not None:
                        g_goal = g + self._shot_cost(pose, poses)
                        if g_goal < best_goal:
                            best_goal = g_goal
                            X.append(gx)
                            Y.append(gy)
                            N.append(n)
                            R.append(-1)
                            C.append(-1)
                            G.append(g_goal)
                            parent.append(i)
                            prim.append(_SHOT)
                            goal_flag.append(True)
                            KEY.append(-1)
                            shots[len(X) - 1] = poses
                            heapq.heappush(open_list, (g_goal, counter, len(X) - 1))
                            counter += 1

            cells, ends, bins, fallback = tables.get(n) or table(n)
            shift[0, 0] = y * inv_res - offset_y
            shift[1, 0] = x * inv_res - offset_x
            q = np.floor(cells + shift).astype(np.int64)
            idx = np.ravel_multi_index(q, padded_shape, mode="clip")
            hit = blocked_flat[idx].reshape(3, -1).any(axis=1).tolist()
            r0, c0 = R[i], C[i]
            for j in range(3):
                if hit[j]:
                    continue
                xn, yn = x + ends[j][0], y + ends[j][1]
                nn = n + turn_steps[j]
                key_n = ((int((yn - y0) / cell) * nx_closed + int((xn - x0) / cell)) * n_bins
                         + bins[j])
                if key_n in closed:
                    continue
                rn = int((yn - y0) * inv_res)
                cn = int((xn - x0) * inv_res)
                k = bin_table[(rn - r0 + reach) * bin_row + (cn - c0 + reach)]
                if k < 0:
                    k = fallback[j]
                cost = cost_flat[(k * H + rn) * W + cn]
                gn = g + edge_cost(s, amplified_cost(float(cost), beta))
                if gn >= best_g.get(key_n, math.inf) or gn >= best_goal:
                    continue
                goal_n = is_goal(xn, yn, nn)
                if goal_n:
                    hn = 0.0
                else:
                    hn = hypot(xn - gx, yn - gy)
                    if h_grid is not None:
                        flat = rn * W + cn
                        hn = max(h_grid[flat], hn + h_terrain[flat])
                        if hn == math.inf:
                            continue
                best_g[key_n] = gn
                X.append(xn)
                Y.append(yn)
                N.append(nn)
                R.append(rn)
                C.append(cn)
                G.append(gn)
                parent.append(i)
                prim.append(j)
                goal_flag.append(goal_n)
                KEY.append(key_n)
                if goal_n:
                    best_goal = min(best_goal, gn)
                heappush(open_list, (gn + weight * hn, counter, len(X) - 1))
                counter += 1
        return failure("no path: every reachable pose was expanded (open list exhausted)",
                       len(expanded), expanded)

    def _result(self, goal_id, X, Y, N, G, parent, prim, shots, curvatures, sub_t, sth,
                dtheta, expansions, expanded, t0) -> PlanResult:
        chain = []
        i = goal_id
        while i >= 0:
            chain.append(i)
            i = parent[i]
        chain.reverse()
        pieces = [np.array([[X[chain[0]], Y[chain[0]], sth]])]
        nodes = [(X[chain[0]], Y[chain[0]], sth)]
        for i in chain[1:]:
            p = parent[i]
            if prim[i] == _SHOT:
                piece = shots[i]
            else:
                piece = arc_poses((X[p], Y[p], sth + N[p] * dtheta), curvatures[prim[i]], sub_t)
            pieces.append(piece)
            nodes.append(tuple(piece[-1]))
        path = np.concatenate(pieces)
        path[:, 2] = wrap_angle(path[:, 2])
        nodes = np.asarray(nodes, dtype=np.float64)
        nodes[:, 2] = wrap_angle(nodes[:, 2])
        return PlanResult(
            path=path,
            cost=float(G[goal_id]),
            expansions=expansions,
            time_s=time.perf_counter() - t0,
            success=True,
            reason="reached goal",
            nodes=nodes,
            node_costs=np.asarray([G[i] for i in chain], dtype=np.float64),
            expanded_xy=np.asarray(expanded, dtype=np.float64).reshape(-1, 2),
        )


def _check_config(cfg: PlannerConfig) -> None:
    if cfg.heuristic not in HEURISTICS:
        raise ValueError(f"heuristic must be one of {HEURISTICS}, got {cfg.heuristic!r}")
    positive = ("step_m", "goal_tolerance_m", "goal_heading_tolerance_rad", "max_time_s",
                "closed_cell_m", "substep_m")
    for name in positive:
        if not getattr(cfg, name) > 0:
            raise ValueError(f"PlannerConfig.{name} must be > 0, got {getattr(cfg, name)}")
    if cfg.heuristic_weight < 1:
        raise ValueError(f"PlannerConfig.heuristic_weight must be ≥ 1, got {cfg.heuristic_weight}")
    if cfg.beta < 0:
        raise ValueError(f"PlannerConfig.beta must be ≥ 0, got {cfg.beta}")
    if cfg.theta_bins < 1 or cfg.max_expansions < 1:
        raise ValueError("PlannerConfig.theta_bins and max_expansions must be ≥ 1")
    if cfg.shot_distance_m < 0:
        raise ValueError(f"PlannerConfig.shot_distance_m must be ≥ 0, got {cfg.shot_distance_m}")
    if cfg.safety_margin_m < 0:
        raise ValueError(f"PlannerConfig.safety_margin_m must be ≥ 0, got {cfg.safety_margin_m}")


def plan(
    start,
    goal,
    costmap: np.ndarray,
    occupancy: np.ndarray,
    grid: GridSpec,
    *,
    min_turn_radius_m: float,
    footprint: tuple[float, float],
    cfg: PlannerConfig | None = None,
) -> PlanResult:
    """One query: ``HybridAStar(costmap, occupancy, grid, ...).plan(start, goal)``.

    start (x, y, θ), goal (x, y) or (x, y, θ) [m, m, rad]; costmap (K, H, W) in
    [0, 1]; occupancy (H, W) uint8; footprint (length_m, width_m). See
    :class:`HybridAStar`. For several queries on one map, build the planner once.
    """
    planner = HybridAStar(
        costmap, occupancy, grid, min_turn_radius_m=min_turn_radius_m, footprint=footprint, cfg=cfg
    )
    return planner.plan(start, goal)
