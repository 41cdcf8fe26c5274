"""The grid Dijkstra of the 2D cost-to-go (:class:`~.heuristics.CostToGo`), compiled with
numba: ``scipy.sparse.csgraph.dijkstra`` on the reversed 8-connected graphs of its two
relaxations, without building them, run only as far as the search needs.

The move u → v = u + moves[m] (both cells passable) costs weights[v, m] (∞: no such
move). A run's state lives in four arrays (:class:`DijkstraRun`) so that it can stop and
go on: the compiled search settles cells only as it needs their bound (:func:`settle`),
and a run taken to the end (:func:`grid_dijkstra`) gives every cell's. The heap is an
indexed binary heap ordered by dist; each distance is the sum dist[v] + w that scipy's
dijkstra forms on the same graph, so it is the same to the bit, however far a run went.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class DijkstraRun(NamedTuple):
    """One run's state: ``dist`` (n,) distances, ``heap`` (n,) the indexed heap of cells,
    ``where`` (n,) each cell's heap slot (−1 never queued, −2 settled), ``size`` (1,)."""

    dist: np.ndarray
    heap: np.ndarray
    where: np.ndarray
    size: np.ndarray


class Relaxations(NamedTuple):
    """One goal's two relaxations D and D_c: ``passable`` (H·W,) bool, ``moves`` (8, 2)
    (Δrow, Δcol), edge weights ``w_full`` and ``w_terrain`` (H·W, 8) and their runs
    ``full`` and ``terrain`` (a 1-cell dummy when ``zero_terrain``: D_c = 0 wherever D is
    finite), ``phi`` φ, ``height`` and ``width`` of the grid."""

    passable: np.ndarray
    moves: np.ndarray
    w_full: np.ndarray
    w_terrain: np.ndarray
    full: DijkstraRun
    terrain: DijkstraRun
    zero_terrain: bool
    phi: float
    height: int
    width: int


def new_run(n: int) -> DijkstraRun:
    """The arrays of a run over n cells (seed it with :func:`dijkstra_seed`)."""
    return DijkstraRun(np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64),
                       np.zeros(1, np.int64))


@njit(cache=True)
def dijkstra_seed(sources, dist, heap, where, size):
    """Start a run: dist = ∞ and where = −1 (never queued) everywhere, then the sources
    at distance 0. where[c] = −2 marks a settled cell."""
    dist[:] = np.inf
    where[:] = -1
    n = 0
    for src in sources:
        if where[src] != -1:
            continue
        dist[src] = 0.0
        heap[n] = src
        where[src] = n
        n += 1
    size[0] = n


@njit(cache=True)
def settle(target, height, width, passable, weights, moves, dist, heap, where, size):
    """Go on with a run until cell ``target`` is settled (−1: until every reachable cell
    is) or nothing is left to settle; dist[target] is then final (∞: unreachable)."""
    n = size[0]
    while n > 0 and (target < 0 or where[target] != -2):
        v = heap[0]
        where[v] = -2
        n -= 1
        if n > 0:  # move the last cell to the root and sift it down
            last = heap[n]
            d_last = dist[last]
            i = 0
            while True:
                child = 2 * i + 1
                if child >= n:
                    break
                if child + 1 < n and dist[heap[child + 1]] < dist[heap[child]]:
                    child += 1
                if dist[heap[child]] < d_last:
                    heap[i] = heap[child]
                    where[heap[i]] = i
                    i = child
                else:
                    break
            heap[i] = last
            where[last] = i
        row, col = v // width, v % width
        dv = dist[v]
        for m in range(8):
            w = weights[v, m]
            if w == np.inf:
                continue
            ur, uc = row - moves[m, 0], col - moves[m, 1]
            if ur < 0 or ur >= height or uc < 0 or uc >= width:
                continue
            u = ur * width + uc
            if where[u] == -2 or not passable[u]:
                continue
            alt = dv + w
            if alt < dist[u]:
                dist[u] = alt
                i = where[u]
                if i == -1:
                    i = n
                    n += 1
                while i > 0:  # sift up
                    parent = (i - 1) >> 1
                    if dist[heap[parent]] > alt:
                        heap[i] = heap[parent]
                        where[heap[i]] = i
                        i = parent
                    else:
                        break
                heap[i] = u
                where[u] = i
    size[0] = n


@njit(cache=True)
def grid_dijkstra(height, width, passable, weights, moves, sources):
    """Distances (H·W,) from the ``sources`` (flat cells): one run taken to the end."""
    n = height * width
    dist, heap, where = np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64)
    size = np.zeros(1, np.int64)
    dijkstra_seed(sources, dist, heap, where, size)
    settle(-1, height, width, passable, weights, moves, dist, heap, where, size)
    return dist



@njit(cache=True)
def bounds_at(flat, r):
    """(φ·D, φ·D_c) at cell ``flat`` of :class:`Relaxations` ``r``, settling both runs as
    far as needed; with ``r.zero_terrain`` D_c is 0 wherever D is finite."""
    full, terrain = r.full, r.terrain
    if full.where[flat] != -2:
        settle(flat, r.height, r.width, r.passable, r.w_full, r.moves, full.dist, full.heap,
               full.where, full.size)
    h_full = r.phi * full.dist[flat]
    if r.zero_terrain:
        return h_full, r.phi * (0.0 if full.dist[flat] != np.inf else np.inf)
    if terrain.where[flat] != -2:
        settle(flat, r.height, r.width, r.passable, r.w_terrain, r.moves, terrain.dist,
               terrain.heap, terrain.where, terrain.size)
    return h_full, r.phi * terrain.dist[flat]
