"""The search's cost-to-go estimates.

- ``"euclidean"`` (the paper's): h = distance from the pose to the goal point.
- ``"cost_to_go"``: max(φ·D, d + φ·D_c), a direction-aware 2D lower bound
  (:class:`CostToGo`), which also refutes unreachable goals before the search.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from typing import NamedTuple

import numpy as np
from scipy import ndimage

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import TWO_PI, GridSpec, angle_diff
from dgt_lib.navigation.planner.primitives import amplified_cost, distance

HEURISTICS: tuple[str, ...] = ("euclidean", "cost_to_go")

_CACHED_GOALS = 4  # cost-to-go fields kept per map (most recently used goals)


def euclidean(x: float, y: float, gx: float, gy: float) -> float:
    """h = ‖(x, y) − (gx, gy)‖ [m], the paper's heuristic (admissible: g_edge ≥ s)."""
    return distance(x - gx, y - gy)


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


class CostToGo:
    """The 2D cost-to-go lower bound of one map, per goal (the last few goals cached).

    Two direction-aware 2D relaxations on the 8-connected grid, solved per goal by the
    compiled Dijkstra runs of :mod:`.compiled_dijkstra` (scipy's distances on the same
    graphs, to the bit: ``tests/test_planner_exact.py``), only as far as asked: D prices a
    grid move by its length times (1 + the least amplified cost C' = C(1 + βC) near the
    cell in the layers the move may read), D_c by the terrain part alone; with φ = s/O (O
    the longest octile cell jump of one step) the bound is h = max(φ·D, max(d − tol, 0) +
    φ·D_c), d the distance to the goal point. The definitions and the proof that it is a
    lower bound: docs/planner.md.

    costmap: (K, H, W) in [0, 1]; blocked: (H, W) cells a footprint centre may
    not occupy; occupied_distance: (H, W) distance [m] from each cell centre to
    the nearest occupied/unobserved centre; clearance_m: the distance below
    which a cell is blocked; substep_m: the actual sub-step spacing Δ.
    """

    def __init__(self, costmap: np.ndarray, blocked: np.ndarray, occupied_distance: np.ndarray,
                 grid: GridSpec, cfg: PlannerConfig, *, clearance_m: float,
                 min_turn_radius_m: float, substep_m: float):
        self.costmap = costmap
        self.blocked = blocked
        self.occupied_distance = occupied_distance
        self.grid = grid
        self.cfg = cfg
        self.clearance_m = clearance_m
        self.min_turn_radius_m = min_turn_radius_m
        self.substep_m = substep_m
        self.impassable: np.ndarray | None = None
        self._moves: Moves | None = None
        self._template: tuple | None = None  # the runs' per-map part, and the dearest move
        self.cache: OrderedDict = OrderedDict()

    def field(self, goal_xy) -> np.ndarray:
        """(H, W) bound h of every cell [cost units] (∞ where the goal is unreachable)."""
        h_full, h_terrain = self.bounds(goal_xy)
        X, Y = self.grid.cell_centers()
        half_diagonal = self.grid.resolution * math.sqrt(2) / 2
        d = np.hypot(X - float(goal_xy[0]), Y - float(goal_xy[1])) - half_diagonal
        return np.maximum(h_full, np.maximum(d - self.cfg.goal_tolerance_m, 0.0) + h_terrain)

    def bounds(self, goal_xy) -> tuple[np.ndarray, np.ndarray]:
        """(φ·D, φ·D_c), each (H, W), for one goal (cached)."""
        entry = self._entry(goal_xy)
        if entry[0] is None:  # the runs go as far as the search asked: take them to the end
            from dgt_lib.navigation.planner.compiled_dijkstra import settle

            r = entry[1]
            settle(-1, r, r.full)
            if not r.zero_terrain:
                settle(-1, r, r.terrain)
            full = r.full.dist  # D_c = 0 wherever D is finite on a zero-terrain map
            terrain = np.where(np.isfinite(full), 0.0, np.inf) if r.zero_terrain else \
                r.terrain.dist
            entry[0] = tuple(r.phi * d.reshape(self.grid.shape) for d in (full, terrain))
        return entry[0]

    def runs(self, goal_xy):
        """The goal's two Dijkstra runs (:class:`.compiled_dijkstra.Relaxations`), settled
        as far as anyone asked: what the compiled search reads its bound from (cached like
        :meth:`bounds`)."""
        return self._entry(goal_xy)[1]

    def _entry(self, goal_xy) -> list:
        """The cache entry of one goal: [bounds or None, runs]."""
        gx, gy = float(goal_xy[0]), float(goal_xy[1])
        key = (gx, gy)
        if key in self.cache:
            self.cache.move_to_end(key)
            return self.cache[key]
        from dgt_lib.navigation.planner.compiled_dijkstra import new_run

        template, dearest_m = self._runs_template()
        source, n = self._goal_cells(gx, gy), template.passable.size
        self.cache[key] = [None, template._replace(
            full=new_run(n, source, float(template.lengths.min()), dearest_m),
            terrain=new_run(1, source[:0]) if template.zero_terrain else new_run(n, source))]
        while len(self.cache) > _CACHED_GOALS:
            self.cache.popitem(last=False)
        return self.cache[key]

    def _runs_template(self) -> tuple:
        """(:class:`.compiled_dijkstra.Relaxations` without runs, the dearest move of D
        [m]): what every goal's runs share, built once per map."""
        if self._template is None:
            from dgt_lib.navigation.planner.compiled_dijkstra import Relaxations, new_run

            moves = self._relaxation_moves()
            layers = moves.layers.reshape(len(moves.layers), -1)
            finite = layers[np.isfinite(layers)]
            one_layer, none = len(layers) == 1, new_run(1, np.zeros(0, np.int64))
            prices = np.zeros((1, 8)) if one_layer else np.ascontiguousarray(np.stack(
                [layers[moves.near[m]].min(axis=0) for m in range(8)], axis=1))  # T_m(v)
            phi = self.cfg.step_m / step_cell_bounds(self.cfg.step_m, self.grid.resolution)[0]
            self._template = (Relaxations(
                moves.passable.ravel(), moves.steps, moves.lengths, one_layer, layers[0], prices,
                none, none, not np.any(finite), phi, *self.grid.shape),
                float(moves.lengths.max()) * (1.0 + (finite.max() if finite.size else 0.0)))
        return self._template

    def _goal_cells(self, gx: float, gy: float) -> np.ndarray:
        """The flat indices, ascending, of the passable cells whose centre lies within
        tolerance + res·√2/2 of the goal (x, y) [m]: the runs' sources. Only the cells of
        a window around the goal are measured (one cell wider than the disc)."""
        grid, (H, W) = self.grid, self.grid.shape
        reach = self.cfg.goal_tolerance_m + grid.resolution * math.sqrt(2) / 2
        (r0, r1), (c0, c1) = grid.xy_to_cell((gx - reach, gx + reach), (gy - reach, gy + reach))
        rows, cols = np.mgrid[max(r0 - 1, 0):min(r1 + 2, H), max(c0 - 1, 0):min(c1 + 2, W)]
        X, Y = grid.cell_to_xy(rows, cols)
        inside = (np.hypot(X - gx, Y - gy) <= reach) & ~self.impassable[rows, cols]
        return (rows * W + cols)[inside]

    def _relaxation_moves(self) -> Moves:
        """The per-map part of both relaxations (built once): which cells are passable
        and the terrain price F_k of entering each cell per distinct layer."""
        if self._moves is not None:
            return self._moves
        cfg, res = self.cfg, self.grid.resolution
        s = cfg.step_m
        rho = (step_cell_bounds(s, res)[1] + res / 2) / res  # [cells]
        half = math.floor(rho)
        d = np.arange(-half, half + 1)
        disk = np.hypot(d[:, None], d[None, :]) <= rho
        # F_k: min of C'_k over the unblocked cells within ρ (a pose's cell is unblocked)
        layers, distinct = [], []  # distinct[k]: the index in layers of layer k's F
        for layer in self.costmap:
            same = next((i for i, prev in enumerate(layers) if np.array_equal(prev, layer)),
                        None)
            if same is None:  # equal layers (an isotropic or zero costmap): filter once
                same = len(layers)
                layers.append(layer)
            distinct.append(same)
        least = np.stack([disk_minimum(np.where(self.blocked, np.inf,
                                                amplified_cost(layer, cfg.beta)), disk)
                          for layer in layers])
        sagitta = s * s / (8 * self.min_turn_radius_m)
        slack = res / 2 + math.sqrt(2) * res + sagitta + self.substep_m / 2
        self.impassable = self.occupied_distance < self.clearance_m - slack
        n_headings = len(self.costmap)
        theta_k = TWO_PI * np.arange(n_headings) / n_headings
        steps, lengths, near = [], [], np.zeros((8, len(layers)), dtype=bool)
        spread = math.pi / 4 + math.pi / n_headings + 1e-9
        for m in range(8):
            psi = m * math.pi / 4
            dr, dc = round(math.sin(psi)), round(math.cos(psi))
            steps.append((dr, dc))
            lengths.append(res * math.hypot(dr, dc))
            for k in np.flatnonzero(np.abs(angle_diff(theta_k, psi)) <= spread):
                near[m, distinct[k]] = True
        self._moves = Moves(~self.impassable, np.asarray(steps, dtype=np.int64),
                            np.asarray(lengths), least, near)
        return self._moves


class Moves(NamedTuple):
    """The 8 grid moves of the 2D relaxations: passable (H, W) bool; steps (8, 2) (Δrow,
    Δcol) of move m (direction m·45°); lengths (8,) [m]; layers (U, H, W) the terrain price
    F of entering each cell, one per distinct costmap layer (∞: no unblocked cell within
    ρ); near (8, U) bool, the layers move m may read (S_m)."""

    passable: np.ndarray
    steps: np.ndarray
    lengths: np.ndarray
    layers: np.ndarray
    near: np.ndarray


def disk_minimum(values: np.ndarray, disk: np.ndarray) -> np.ndarray:
    """``ndimage.minimum_filter(values, footprint=disk, mode="constant", cval=inf)`` for a
    symmetric disk (odd side, convex rows), as one 1D minimum filter per distinct row width
    and a shifted minimum per row: the same values, several times faster."""
    half = disk.shape[0] // 2
    widths = [int(np.flatnonzero(row).size) for row in disk]
    rows = {w: ndimage.minimum_filter1d(values, w, axis=1, mode="constant", cval=np.inf)
            for w in set(widths) if w > 0}
    out = np.full(values.shape, np.inf)
    H = values.shape[0]
    for i, w in enumerate(widths):
        if w == 0:
            continue
        dy = i - half  # out[r] takes row r + dy
        src = rows[w]
        if dy >= 0:
            np.minimum(out[:H - dy], src[dy:], out=out[:H - dy])
        else:
            np.minimum(out[-dy:], src[:H + dy], out=out[-dy:])
    return out
