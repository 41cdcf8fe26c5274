"""The grid Dijkstra of the 2D cost-to-go (:class:`~.heuristics.CostToGo`), compiled with
numba: ``scipy.sparse.csgraph.dijkstra`` on the reversed 8-connected graphs of its two
relaxations, without building them, run only as far as the search needs.

The move u → v = u + moves[m] (both cells passable) costs ℓ_m·(1 + T_m(v)) in D and
ℓ_m·T_m(v) in D_c, T_m(v) the least terrain price of the layers move m may read (∞: no
such move; :func:`move_prices`, as :meth:`~.heuristics.Moves.least` forms it for scipy's
graphs). A run's state lives in arrays so that it can stop and go on:
the compiled search settles cells only as it needs their bound (:func:`bounds_at`),
:meth:`~.heuristics.DijkstraRuns.finish` every cell.

Every move of D costs at least δ = res, so D is a bucket queue (Dial's algorithm,
:func:`settle_buckets`): cells are queued by ⌊dist/δ'⌋ with δ' just under δ, and a
bucket's cells are all final when it is reached, in any order. D_c has moves of cost 0 and
keeps a binary heap (:func:`settle_heap`). Both settle a cell at the distance scipy's
dijkstra gives it, to the bit, however far a run went: each distance is the least sum
dist[v] + w over the cell's settled neighbours, whatever the order they were settled in.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


class DijkstraRun(NamedTuple):
    """A run on a binary heap: ``dist`` (n,) distances, the heap's ``keys`` (n,) and
    ``cells`` (n,), ``where`` (n,) each cell's heap slot (−1 never queued, −2 settled),
    ``size`` (1,)."""

    dist: np.ndarray
    keys: np.ndarray
    cells: np.ndarray
    where: np.ndarray
    size: np.ndarray


class BucketRun(NamedTuple):
    """A run on a bucket queue: ``dist`` (n,) distances, each queued cell in a doubly
    linked list (``next``, ``prev`` (n,)) of its bucket, ``where`` (n,) its bucket's slot
    in the ring ``heads`` (R,) of list heads (−1 never queued, −2 settled); ``state`` (2,)
    the bucket being settled and the number of queued cells; ``scale`` 1/δ' [1/m]."""

    dist: np.ndarray
    next: np.ndarray
    prev: np.ndarray
    where: np.ndarray
    heads: np.ndarray
    state: np.ndarray
    scale: float


class Relaxations(NamedTuple):
    """One goal's two relaxations D and D_c: ``passable`` (H·W,) bool, ``moves`` (8, 2)
    (Δrow, Δcol) and ``lengths`` (8,) ℓ_m [m]; the terrain price T_m(v) of entering cell v
    by move m: ``first_layer[v]`` (H·W,) for every m where ``one_layer`` (all costmap
    layers equal), else ``prices[v, m]`` (H·W, 8) (:func:`move_prices`); the runs ``full``
    of D and ``terrain`` of D_c (a 1-cell dummy when ``zero_terrain``: D_c = 0 wherever D
    is finite), ``phi`` φ, ``height`` and ``width`` of the grid."""

    passable: np.ndarray
    moves: np.ndarray
    lengths: np.ndarray
    one_layer: bool
    first_layer: np.ndarray
    prices: np.ndarray
    full: BucketRun
    terrain: DijkstraRun
    zero_terrain: bool
    phi: float
    height: int
    width: int


def heap_run(n: int, sources: np.ndarray) -> DijkstraRun:
    """A heap run over n cells from the flat cells ``sources`` (at distance 0)."""
    run = DijkstraRun(np.full(n, np.inf), np.empty(n), np.empty(n, np.int64),
                  np.full(n, -1, np.int64), np.zeros(1, np.int64))
    sources = np.unique(sources)
    run.dist[sources], run.keys[:len(sources)], run.cells[:len(sources)] = 0.0, 0.0, sources
    run.where[sources], run.size[0] = np.arange(len(sources)), len(sources)
    return run


def bucket_run(n: int, sources: np.ndarray, least_move_m: float,
               most_move_m: float) -> BucketRun:
    """A bucket run over n cells from the flat cells ``sources`` (at distance 0), for moves
    that cost least_move_m to most_move_m [m]."""
    width = least_move_m * (1.0 - 1e-6)  # δ': a move always reaches a later bucket
    heads = np.full(math.ceil(most_move_m / width) + 3, -1, np.int64)
    run = BucketRun(np.full(n, np.inf), np.empty(n, np.int64), np.empty(n, np.int64),
                    np.full(n, -1, np.int64), heads, np.zeros(2, np.int64), 1.0 / width)
    for cell in np.unique(sources):
        _link(run, int(cell), 0)
        run.dist[cell] = 0.0
    run.state[1] = len(np.unique(sources))
    return run


@njit(cache=True, inline="always")
def _link(run, cell, slot):
    """Put ``cell`` at the head of bucket ``slot``'s list."""
    head = run.heads[slot]
    run.next[cell], run.prev[cell] = head, -1
    if head >= 0:
        run.prev[head] = cell
    run.heads[slot] = cell
    run.where[cell] = slot


@njit(cache=True)
def move_prices(layers, near, near_start):
    """(n, 8) T_m(v): the least terrain price over the layers move m reads
    (``near[near_start[m]:near_start[m + 1]]`` of ``layers`` (U, n)) at each cell v."""
    out = np.empty((layers.shape[1], 8))
    for v in range(layers.shape[1]):
        for m in range(8):
            t = np.inf
            for j in range(near_start[m], near_start[m + 1]):
                t = min(t, layers[near[j], v])
            out[v, m] = t
    return out


@njit(cache=True)
def settle_buckets(target, r, run):
    """Go on with D's bucket run until cell ``target`` is settled (−1: until every
    reachable cell is) or nothing is left to settle; dist[target] is then final (∞:
    unreachable)."""
    height, width, passable, moves, lengths = r.height, r.width, r.passable, r.moves, r.lengths
    one_layer, first_layer, prices = r.one_layer, r.first_layer, r.prices
    dist, nxt, prev, where, heads = run.dist, run.next, run.prev, run.where, run.heads
    n_slots, scale = heads.shape[0], run.scale
    bucket, queued = run.state[0], run.state[1]
    while queued > 0 and (target < 0 or where[target] != -2):
        slot = bucket % n_slots
        v = heads[slot]
        if v < 0:
            bucket += 1
            continue
        heads[slot] = nxt[v]  # settle the bucket's first cell
        if nxt[v] >= 0:
            prev[nxt[v]] = -1
        where[v] = -2
        queued -= 1
        dv = dist[v]
        row = v // width
        col = v - row * width
        for m in range(8):
            ur, uc = row - moves[m, 0], col - moves[m, 1]
            if ur < 0 or ur >= height or uc < 0 or uc >= width:
                continue
            u = ur * width + uc
            old = where[u]
            if old == -2 or not passable[u]:
                continue
            if one_layer:  # T_m(v), the terrain price of entering v by move m
                t = first_layer[v]
            else:
                t = prices[v, m]
            if t == np.inf:
                continue
            alt = dv + (lengths[m] + lengths[m] * t)
            if alt < dist[u]:
                dist[u] = alt
                new = np.int64(alt * scale) % n_slots
                if old == new:
                    continue
                if old >= 0:  # unlink u from its old bucket
                    if prev[u] >= 0:
                        nxt[prev[u]] = nxt[u]
                    else:
                        heads[old] = nxt[u]
                    if nxt[u] >= 0:
                        prev[nxt[u]] = prev[u]
                else:
                    queued += 1
                _link(run, u, new)
    run.state[0], run.state[1] = bucket, queued


@njit(cache=True)
def settle_heap(target, r, run):
    """Go on with D_c's heap run until cell ``target`` is settled (−1: until every
    reachable cell is) or nothing is left to settle; dist[target] is then final (∞:
    unreachable)."""
    height, width, passable, moves, lengths = r.height, r.width, r.passable, r.moves, r.lengths
    one_layer, first_layer, prices = r.one_layer, r.first_layer, r.prices
    dist, keys, cells, where = run.dist, run.keys, run.cells, run.where
    n = run.size[0]
    while n > 0 and (target < 0 or where[target] != -2):
        v, dv = cells[0], keys[0]
        where[v] = -2
        n -= 1
        if n > 0:  # the hole at the root goes down along the lesser children to a leaf,
            i = 0  # then the last entry goes up from there (fewer unpredictable branches)
            while True:
                child = 2 * i + 1
                if child + 1 < n:
                    child += np.int64(keys[child + 1] < keys[child])
                elif child >= n:
                    break
                keys[i], cells[i] = keys[child], cells[child]
                where[cells[i]] = i
                i = child
            _sift_up(keys, cells, where, i, keys[n], cells[n])
        row = v // width
        col = v - row * width
        for m in range(8):
            ur, uc = row - moves[m, 0], col - moves[m, 1]
            if ur < 0 or ur >= height or uc < 0 or uc >= width:
                continue
            u = ur * width + uc
            if where[u] == -2 or not passable[u]:
                continue
            if one_layer:  # T_m(v), the terrain price of entering v by move m
                t = first_layer[v]
            else:
                t = prices[v, m]
            if t == np.inf:
                continue
            alt = dv + lengths[m] * t
            if alt < dist[u]:
                dist[u] = alt
                i = where[u]
                if i == -1:
                    i = n
                    n += 1
                _sift_up(keys, cells, where, i, alt, u)
    run.size[0] = n


@njit(cache=True, inline="always")
def _sift_up(keys, cells, where, i, key, cell):
    """Put (key, cell) into the heap at slot i or above, moving greater parents down."""
    while i > 0:
        parent = (i - 1) >> 1
        if keys[parent] > key:
            keys[i], cells[i] = keys[parent], cells[parent]
            where[cells[i]] = i
            i = parent
        else:
            break
    keys[i], cells[i] = key, cell
    where[cell] = i


@njit(cache=True, inline="always")
def bounds_at(flat, r):
    """(φ·D, φ·D_c) at cell ``flat`` of :class:`Relaxations` ``r``, settling both runs as
    far as needed; with ``r.zero_terrain`` D_c is 0 wherever D is finite."""
    full, terrain = r.full, r.terrain
    if full.where[flat] != -2:
        settle_buckets(flat, r, full)
    h_full = r.phi * full.dist[flat]
    if r.zero_terrain:
        return h_full, r.phi * (0.0 if full.dist[flat] != np.inf else np.inf)
    if terrain.where[flat] != -2:
        settle_heap(flat, r, terrain)
    return h_full, r.phi * terrain.dist[flat]
