"""The grid Dijkstra of the 2D cost-to-go (:class:`~.heuristics.CostToGo`), compiled with
numba: ``scipy.sparse.csgraph.dijkstra`` on the reversed 8-connected graphs of its two
relaxations, without building them, run only as far as the search needs.

The move u → v = u + moves[m] (both cells passable) costs ℓ_m·(1 + T_m(v)) in D and
ℓ_m·T_m(v) in D_c, T_m(v) the least terrain price of the layers move m may read (∞: no
such move). A run's state lives in arrays so that it can stop and go on: the compiled
search settles cells only as it needs their bound (:func:`settle_cell`),
:meth:`~.heuristics.CostToGo.bounds` every cell.

Every move of D costs at least δ = res, so D's run is a bucket queue (Dial's algorithm):
cells are queued by ⌊dist/δ'⌋ with δ' just under δ, and a bucket's cells are all final when
it is reached, in any order. D_c has moves of cost 0 and keeps a binary heap. Both settle a
cell at the distance scipy's dijkstra gives it, to the bit, however far a run went: each
distance is the least sum dist[v] + w over the cell's settled neighbours, whatever the
order they were settled in.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


class DijkstraRun(NamedTuple):
    """One run's state: ``dist`` (n,) distances, ``where`` (n,) each cell's place in the
    queue (−1 never queued, −2 settled), ``state`` (2,) the bucket being settled and the
    number of cells queued. D's run is a bucket queue (``scale`` = 1/δ' [1/m]): each queued
    cell in a doubly linked list (``next``, ``prev`` (n,)) of its bucket, whose slot in the
    ring ``heads`` (R,) of list heads is its ``where``. D_c's is a binary heap (``scale`` =
    0) of entries (``keys``, ``cells``) (n,), ``where`` each cell's slot."""

    dist: np.ndarray
    where: np.ndarray
    next: np.ndarray
    prev: np.ndarray
    heads: np.ndarray
    keys: np.ndarray
    cells: np.ndarray
    state: np.ndarray
    scale: float


class Relaxations(NamedTuple):
    """One goal's two relaxations D and D_c: ``passable`` (H·W,) bool, ``moves`` (8, 2)
    (Δrow, Δcol) and ``lengths`` (8,) ℓ_m [m]; the terrain price T_m(v) of entering cell v
    by move m: ``first_layer[v]`` (H·W,) for every m where ``one_layer`` (all costmap
    layers equal), else ``prices[v, m]`` (H·W, 8); the runs ``full``
    of D and ``terrain`` of D_c (a 1-cell dummy when ``zero_terrain``: D_c = 0 wherever D
    is finite), ``phi`` φ, ``height`` and ``width`` of the grid."""

    passable: np.ndarray
    moves: np.ndarray
    lengths: np.ndarray
    one_layer: bool
    first_layer: np.ndarray
    prices: np.ndarray
    full: DijkstraRun
    terrain: DijkstraRun
    zero_terrain: bool
    phi: float
    height: int
    width: int


def new_run(n: int, sources: np.ndarray, bucket_m: float = 0.0,
            most_move_m: float = 0.0) -> DijkstraRun:
    """A run over n cells from the flat cells ``sources`` (distinct, at distance 0): D's
    bucket queue for moves that cost bucket_m to most_move_m [m], or D_c's heap (bucket_m =
    0)."""
    k, bucketed = len(sources), bucket_m > 0
    width = bucket_m * (1.0 - 1e-6)  # δ': a move always reaches a later bucket
    lists, heap = (n, 1) if bucketed else (1, n)
    run = DijkstraRun(np.full(n, np.inf), np.full(n, -1, np.int64),
                      np.full(lists, -1, np.int64), np.full(lists, -1, np.int64),
                      np.full(math.ceil(most_move_m / width) + 3 if bucketed else 1, -1,
                              np.int64), np.zeros(heap), np.zeros(heap, np.int64),
                      np.array([0, k]), 1.0 / width if bucketed else 0.0)
    run.dist[sources] = 0.0
    if bucketed and k:  # all in bucket 0, in one list
        run.heads[0], run.where[sources] = sources[0], 0
        run.next[sources[:-1]], run.prev[sources[1:]] = sources[1:], sources[:-1]
    elif k:
        run.cells[:k], run.where[sources] = sources, np.arange(k)
    return run


@njit(cache=True, inline="always")
def _unlink(nxt, prev, heads, cell, slot):
    """Take ``cell`` out of bucket ``slot``'s list."""
    if prev[cell] >= 0:
        nxt[prev[cell]] = nxt[cell]
    else:
        heads[slot] = nxt[cell]
    if nxt[cell] >= 0:
        prev[nxt[cell]] = prev[cell]


@njit(cache=True)
def settle(target, r, run):
    """Go on with ``run`` (``r.full`` or ``r.terrain`` of :class:`Relaxations` ``r``) until
    cell ``target`` is settled (−1: until every reachable cell is) or nothing is left to
    settle; dist[target] is then final (∞: unreachable)."""
    if run.scale > 0:  # each queue its own machine code
        _settle(target, r, run, True)
    else:
        _settle(target, r, run, False)


@njit(cache=True, inline="always")
def _settle(target, r, run, full):
    height, width, passable, moves, lengths = r.height, r.width, r.passable, r.moves, r.lengths
    one_layer, first_layer, prices = r.one_layer, r.first_layer, r.prices
    dist, where, heads, keys, cells = run.dist, run.where, run.heads, run.keys, run.cells
    nxt, prev = run.next, run.prev
    n_slots, scale = heads.shape[0], run.scale
    bucket, n = run.state[0], run.state[1]
    while n > 0 and (target < 0 or where[target] != -2):
        if full:  # the first cell of the first bucket that has one
            v = heads[bucket % n_slots]
            if v < 0:
                bucket += 1
                continue
            _unlink(nxt, prev, heads, v, bucket % n_slots)
            n -= 1
        else:  # the heap's root; the hole goes down along the lesser children to a leaf,
            v, i = cells[0], 0  # then the last entry goes up from there
            n -= 1
            while 2 * i + 1 < n:
                child = 2 * i + 1
                child += np.int64(child + 1 < n and keys[child + 1] < keys[child])
                keys[i], cells[i] = keys[child], cells[child]
                where[cells[i]] = i
                i = child
            if n > 0:
                _sift_up(keys, cells, where, i, keys[n], cells[n])
        where[v] = -2
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
            t = first_layer[v] if one_layer else prices[v, m]  # T_m(v)
            if t == np.inf:
                continue
            alt = dv + (lengths[m] + lengths[m] * t) if full else dv + lengths[m] * t
            if alt < dist[u]:
                dist[u] = alt
                if old == -1:
                    n += 1
                if not full:
                    _sift_up(keys, cells, where, n - 1 if old == -1 else old, alt, u)
                elif old != np.int64(alt * scale) % n_slots:
                    if old >= 0:
                        _unlink(nxt, prev, heads, u, old)
                    slot = np.int64(alt * scale) % n_slots  # u to the head of its list
                    nxt[u], prev[u], where[u] = heads[slot], -1, slot
                    if heads[slot] >= 0:
                        prev[heads[slot]] = u
                    heads[slot] = u
    run.state[0], run.state[1] = bucket, n


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


@njit(cache=True)
def settle_cell(flat, r):
    """Settle cell ``flat`` in both runs of :class:`Relaxations` ``r`` (D_c's only where
    it is run), going on with each as far as needed."""
    if r.full.where[flat] != -2:
        settle(flat, r, r.full)
    if not r.zero_terrain and r.terrain.where[flat] != -2:
        settle(flat, r, r.terrain)


@njit(cache=True, inline="always")
def bound_of(flat, full_dist, terrain_dist, zero_terrain, phi):
    """(φ·D, φ·D_c) at a cell ``flat`` settled in both runs (their ``dist`` arrays); with
    ``zero_terrain`` D_c is 0 wherever D is finite."""
    if zero_terrain:
        return phi * full_dist[flat], phi * (0.0 if full_dist[flat] != np.inf else np.inf)
    return phi * full_dist[flat], phi * terrain_dist[flat]
