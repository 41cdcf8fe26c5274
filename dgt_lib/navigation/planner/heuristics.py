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
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

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

    Two direction-aware 2D relaxations on the 8-connected grid, solved once per goal by
    Dijkstra (scipy's, or ``compiled``: :class:`DijkstraRuns`, the same
    distances): D prices a grid move by its length times (1 + the least amplified cost
    C' = C(1 + βC) near the cell in the layers the move may read), D_c by the terrain part
    alone; with φ = s/O (O the longest octile cell jump of one step) the bound is
    h = max(φ·D, max(d − tol, 0) + φ·D_c), d the distance to the goal point. The
    definitions and the proof that it is a lower bound: docs/planner.md.

    costmap: (K, H, W) in [0, 1]; blocked: (H, W) cells a footprint centre may
    not occupy; occupied_distance: (H, W) distance [m] from each cell centre to
    the nearest occupied/unobserved centre; clearance_m: the distance below
    which a cell is blocked; substep_m: the actual sub-step spacing Δ.
    """

    def __init__(self, costmap: np.ndarray, blocked: np.ndarray, occupied_distance: np.ndarray,
                 grid: GridSpec, cfg: PlannerConfig, *, clearance_m: float,
                 min_turn_radius_m: float, substep_m: float, compiled: bool = False):
        self.costmap = costmap
        self.blocked = blocked
        self.occupied_distance = occupied_distance
        self.grid = grid
        self.cfg = cfg
        self.clearance_m = clearance_m
        self.min_turn_radius_m = min_turn_radius_m
        self.substep_m = substep_m
        self.compiled = compiled  # grid Dijkstra compiled by numba, else scipy's on CSR graphs
        self.impassable: np.ndarray | None = None
        self._moves: Moves | None = None
        self._prices: CompiledPrices | None = None  # what the compiled runs read
        self._graphs: tuple[csr_matrix, csr_matrix] | None = None
        self.cache: OrderedDict = OrderedDict()

    def field(self, goal_xy) -> np.ndarray:
        """(H, W) bound h of every cell [cost units] (∞ where the goal is unreachable)."""
        h_full, h_terrain = self.bounds(goal_xy)
        X, Y = self.grid.cell_centers()
        half_diagonal = self.grid.resolution * math.sqrt(2) / 2
        d = np.hypot(X - float(goal_xy[0]), Y - float(goal_xy[1])) - half_diagonal
        return np.maximum(h_full, np.maximum(d - self.cfg.goal_tolerance_m, 0.0) + h_terrain)

    def bounds(self, goal_xy, as_lists: bool = False) -> tuple:
        """(φ·D, φ·D_c), each (H, W), for one goal (cached); with ``as_lists`` flat
        Python lists (fast scalar lookups in the search loop)."""
        entry = self._entry(goal_xy)
        if entry[0] is None:  # compiled runs the search stopped early: take them to the end
            entry[0] = entry[2].finish()
        if as_lists and entry[1] is None:
            entry[1] = tuple(b.ravel().tolist() for b in entry[0])
        return entry[1 if as_lists else 0]

    def runs(self, goal_xy) -> DijkstraRuns:
        """The goal's two Dijkstra runs, settled as far as anyone asked (``compiled``
        only): what the compiled search reads its bound from (cached like :meth:`bounds`)."""
        entry = self._entry(goal_xy)
        if entry[2] is None:
            raise ValueError("CostToGo.runs needs compiled=True")
        return entry[2]

    def _entry(self, goal_xy) -> list:
        """The cache entry of one goal: [bounds or None, lists or None, runs or None]."""
        gx, gy = float(goal_xy[0]), float(goal_xy[1])
        key = (gx, gy)
        if key in self.cache:
            self.cache.move_to_end(key)
            return self.cache[key]
        res = self.grid.resolution
        moves = self._relaxation_moves()
        source = self._goal_cells(gx, gy)
        phi = self.cfg.step_m / step_cell_bounds(self.cfg.step_m, res)[0]
        if self.compiled:
            entry = [None, None, DijkstraRuns(moves, self._compiled_prices(moves), source,
                                              phi)]
        else:
            if len(source) == 0:
                dists = [np.full(self.grid.shape, np.inf)] * 2
            else:
                if self._graphs is None:
                    self._graphs = self._relaxation_graphs()
                dists = [dijkstra(graph, directed=True, indices=source, min_only=True)
                         for graph in self._graphs]
            entry = [tuple(phi * dist.reshape(self.grid.shape) for dist in dists), None, None]
        self.cache[key] = entry
        while len(self.cache) > _CACHED_GOALS:
            self.cache.popitem(last=False)
        return entry

    def _goal_cells(self, gx: float, gy: float) -> np.ndarray:
        """The flat indices, ascending, of the passable cells whose centre lies within
        tolerance + res·√2/2 of the goal (x, y) [m]: the runs' sources. Only the cells of
        a window around the goal are measured (one cell wider than the disc)."""
        grid, res = self.grid, self.grid.resolution
        reach = self.cfg.goal_tolerance_m + res * math.sqrt(2) / 2
        (r0, r1), (c0, c1) = (
            np.clip(np.asarray(cells) + (-1, 1), 0, n - 1)
            for cells, n in zip(grid.xy_to_cell((gx - reach, gx + reach),
                                                (gy - reach, gy + reach)), grid.shape,
                                strict=True))
        rows, cols = np.mgrid[r0:r1 + 1, c0:c1 + 1]
        X, Y = grid.cell_to_xy(rows, cols)
        inside = (np.hypot(X - gx, Y - gy) <= reach) & ~self.impassable[rows, cols]
        return (rows * grid.width + cols)[inside]

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

    def _compiled_prices(self, moves: Moves) -> CompiledPrices:
        """The terrain prices T_m(v) the compiled runs read (built once per map)."""
        if self._prices is None:
            from dgt_lib.navigation.planner.compiled_dijkstra import move_prices

            layers = moves.layers.reshape(len(moves.layers), -1)
            finite = layers[np.isfinite(layers)]
            near_m, near = np.nonzero(moves.near)
            one_layer = len(layers) == 1
            self._prices = CompiledPrices(
                one_layer, layers[0], np.zeros((1, 8)) if one_layer else
                move_prices(layers, near.astype(np.int64), np.searchsorted(near_m, np.arange(9))),
                not np.any(finite), float(finite.max()) if finite.size else 0.0)
        return self._prices

    def _relaxation_graphs(self) -> tuple[csr_matrix, csr_matrix]:
        """The reversed 8-connected graphs (edge v → u carries the cost of the move
        u → v), for D and D_c, as CSR matrices over flat cell indices."""
        moves = self._relaxation_moves()
        passable, steps, lengths = moves.passable, moves.steps, moves.lengths
        H, W = self.grid.shape
        index = np.arange(H * W).reshape(H, W)
        rows, cols, terrain, edge_lengths = [], [], [], []
        for m, ((dr, dc), length) in enumerate(zip(steps, lengths, strict=True)):
            least_m = moves.least(m)
            # moves u -> v = u + (dr, dc) with both cells passable, charged at v
            u = (slice(max(0, -dr), H - max(0, dr)), slice(max(0, -dc), W - max(0, dc)))
            v = (slice(max(0, dr), H - max(0, -dr)), slice(max(0, dc), W - max(0, -dc)))
            ok = passable[u] & passable[v] & np.isfinite(least_m[v])
            rows.append(index[v][ok])
            cols.append(index[u][ok])
            terrain.append(length * least_m[v][ok])
            edge_lengths.append(np.full(int(ok.sum()), length))
        index_pairs = (np.concatenate(rows), np.concatenate(cols))
        terrain, edge_lengths = np.concatenate(terrain), np.concatenate(edge_lengths)
        shape = (H * W, H * W)
        return (csr_matrix((edge_lengths + terrain, index_pairs), shape=shape),
                csr_matrix((terrain, index_pairs), shape=shape))


class DijkstraRuns:
    """One goal's two relaxations D and D_c as compiled Dijkstra runs that go only as far
    as asked (:func:`.compiled_dijkstra.settle`): the compiled search settles the cells it
    prices, :meth:`finish` every cell. Either way a settled cell holds the distance scipy's
    dijkstra gives it.

    moves: the map's :class:`Moves`; prices: its :class:`CompiledPrices`; source: the
    goal's flat cells; phi: φ (the bound is φ·D). ``relaxations`` is what the compiled search reads
    (:class:`.compiled_dijkstra.Relaxations`)."""

    def __init__(self, moves: Moves, prices: CompiledPrices, source: np.ndarray, phi: float):
        from dgt_lib.navigation.planner.compiled_dijkstra import Relaxations, new_run

        self.shape, self.phi = moves.passable.shape, phi
        self.zero_terrain = prices.zero
        n = moves.passable.size
        full = new_run(n, source, float(moves.lengths.min()),
                       float(moves.lengths.max()) * (1.0 + prices.most))
        terrain = new_run(1, source[:0]) if prices.zero else new_run(n, source)
        self.relaxations = Relaxations(moves.passable.ravel(), moves.steps, moves.lengths,
                                       *prices[:3], full, terrain, prices.zero, float(phi),
                                       int(self.shape[0]), int(self.shape[1]))

    def finish(self) -> tuple[np.ndarray, np.ndarray]:
        """(φ·D, φ·D_c), each (H, W): both runs taken to the end."""
        from dgt_lib.navigation.planner.compiled_dijkstra import settle

        r = self.relaxations
        settle(-1, r, r.full)
        full = r.full.dist
        if self.zero_terrain:
            terrain = np.where(np.isfinite(full), 0.0, np.inf)
        else:
            settle(-1, r, r.terrain)
            terrain = r.terrain.dist
        return tuple(self.phi * d.reshape(self.shape) for d in (full, terrain))


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

    def least(self, m: int) -> np.ndarray:
        """(H, W) the terrain price min_{k ∈ S_m} F_k of entering each cell by move m."""
        return self.layers[self.near[m]].min(axis=0)


class CompiledPrices(NamedTuple):
    """What the compiled runs read of a map's terrain prices: ``one_layer`` (all costmap
    layers equal: T_m(v) = ``first_layer[v]`` (H·W,) for every m), else ``prices`` (H·W, 8)
    T_m(v) (:func:`.compiled_dijkstra.move_prices`); ``zero`` whether every finite price
    is 0 (a zero costmap: D_c = 0 wherever D is finite, its run skipped), ``most`` the
    largest finite price."""

    one_layer: bool
    first_layer: np.ndarray
    prices: np.ndarray
    zero: bool
    most: float


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
