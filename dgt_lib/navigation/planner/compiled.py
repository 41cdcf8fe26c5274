"""One query's Hybrid A* search loop compiled with numba (``backend="compiled"``, the default).

:func:`search` is a line-by-line transcription of the reference search
(:class:`~.search.Search`: ``run``, ``try_shot``, ``expand``, ``is_goal``), with the same
floating-point operations in the same order, so that both backends expand the same nodes
in the same order and return the same plan (``tests/test_planner_exact.py``). It reads
named groups of arrays and scalars — :class:`SearchParams` (the query's constants),
:class:`~.maps.CompiledMaps`, the cost-to-go's :class:`~.compiled_dijkstra.Relaxations`,
:class:`TurnTables`, :class:`NodeArrays`, :class:`OpenList`, :class:`ClosedSet` and
:class:`Progress` — that :mod:`.compiled_search` allocates. Its helpers live in
:mod:`.compiled_kernels` (angles, turn tables, the heap), :mod:`.compiled_shots` (analytic
shots) and :mod:`.compiled_dijkstra` (the 2D cost-to-go).

numba compiles these functions the first time they run in a fresh install (about 10–20 s
on two cores) and caches the machine code beside this file (``cache=True``), so later
processes load them in well under a second.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from dgt_lib.navigation.planner.compiled_dijkstra import bound_of, settle_cell
from dgt_lib.navigation.planner.compiled_kernels import (
    angle_diff,
    build_table,
    distance,
    heap_pop,
    heap_push,
)
from dgt_lib.navigation.planner.compiled_shots import (
    dubins,
    sample_free,
    shot_cost,
    turn_then_straight,
)

# search() return codes
FOUND, EXHAUSTED, CAPPED, PAUSED, OUT_OF_TABLES, NEED_ROOM = 0, 1, 2, 3, 4, 5
SHOT = 3  # result.SHOT


class SearchParams(NamedTuple):
    """The constants of one query. Grid: ``H``, ``W``, ``K`` layers, origin ``x0``, ``y0``
    [m], ``res`` [m] and ``inv_res`` = 1/res; closed set: ``nx_closed`` cells per row of
    ``closed_cell`` [m], ``theta_bins``; ``reach`` of the layer table; blocked map:
    ``pad_width``, ``pad`` and the cell origin (``origin_row``, ``origin_col``) of
    ``BlockedMap.primitive_hits``; primitives: ``n_substeps`` × ``n_circles`` checks,
    ``step`` s [m], ``radius`` r_min [m], ``substep`` Δ [m], ``start_heading`` and
    ``dtheta`` [rad], turn counts −``turn_offset`` … ``turn_offset``; goal: ``gx``, ``gy``,
    ``gth``, ``has_goal_heading``, ``tol2`` (tolerance²), ``heading_tol``; costs: ``beta``,
    ``weight`` w, ``use_cost_to_go``, ``shot_range2`` (−1: no shots), ``max_expansions``."""

    H: int
    W: int
    K: int
    x0: float
    y0: float
    res: float
    inv_res: float
    nx_closed: int
    closed_cell: float
    theta_bins: int
    reach: int
    pad_width: int
    pad: int
    origin_row: float
    origin_col: float
    n_substeps: int
    n_circles: int
    step: float
    radius: float
    substep: float
    start_heading: float
    dtheta: float
    turn_offset: int
    gx: float
    gy: float
    gth: float
    has_goal_heading: bool
    tol2: float
    heading_tol: float
    beta: float
    weight: float
    use_cost_to_go: bool
    shot_range2: float
    max_expansions: int


class TurnTables(NamedTuple):
    """The primitives' geometry per turn count (row t = n + turn_offset), built on first use:
    ``offsets`` (n_circles,) [m] and ``sub_t`` (n_substeps,) [m] to build them, ``have``
    (T,) bool, circle centres ``rows``/``cols`` (T, 3, m) in cells, ``ends`` (T, 3, 2) [m],
    closed-set ``bins`` and ``fallback`` layers (T, 3) (:class:`~.primitives.TurnTable`)."""

    offsets: np.ndarray
    sub_t: np.ndarray
    have: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    ends: np.ndarray
    bins: np.ndarray
    fallback: np.ndarray


class NodeArrays(NamedTuple):
    """The search nodes (:class:`~.result.Node`) as arrays, node i in row i."""

    x: np.ndarray
    y: np.ndarray
    g: np.ndarray
    turns: np.ndarray
    row: np.ndarray
    col: np.ndarray
    parent: np.ndarray
    primitive: np.ndarray
    key: np.ndarray
    is_goal: np.ndarray


class OpenList(NamedTuple):
    """The open list: a binary heap of (``f``, insertion ``count``) → ``node``."""

    f: np.ndarray
    count: np.ndarray
    node: np.ndarray


class ClosedSet(NamedTuple):
    """Per closed-set cell: ``state`` (0 unseen, 1 opened, 2 closed) and ``best_g``."""

    state: np.ndarray
    best_g: np.ndarray


class Progress(NamedTuple):
    """Where the search is, kept between calls: ``expanded`` node ids in order, and
    1-element counters ``n_nodes``, ``heap_size``, ``counter``, ``n_expanded``,
    ``result`` (the goal node) and ``best_goal`` (its g)."""

    expanded: np.ndarray
    n_nodes: np.ndarray
    heap_size: np.ndarray
    counter: np.ndarray
    n_expanded: np.ndarray
    result: np.ndarray
    best_goal: np.ndarray


@njit(cache=True)
def search(p, maps, h, tables, nodes, open_list, closed, progress, stop_at):
    """Run the A* loop of :meth:`.search.Search.run` until the goal is popped (FOUND, the
    goal node in ``progress.result``), the open list empties (EXHAUSTED),
    ``p.max_expansions`` nodes were expanded (CAPPED), ``stop_at`` expansions were reached
    (PAUSED: call again to go on) or a turn count leaves the tables (OUT_OF_TABLES), or
    before an expansion that might overflow the node arrays (NEED_ROOM: grow them all and
    call again).

    p: :class:`SearchParams`; maps: :class:`.maps.CompiledMaps`; h:
    :class:`.compiled_dijkstra.Relaxations` (read only when ``p.use_cost_to_go``);
    tables: :class:`TurnTables`; nodes: :class:`NodeArrays`; open_list: :class:`OpenList`;
    closed: :class:`ClosedSet`; progress: :class:`Progress`."""
    H, W, n_bins = p.H, p.W, p.theta_bins
    nx_closed, reach = p.nx_closed, p.reach
    bin_row = 2 * reach + 1
    use_h, has_gth = p.use_cost_to_go, p.has_goal_heading
    pad_w, pad = p.pad_width, p.pad
    m = p.n_substeps * p.n_circles
    turn_offset, n_tables = p.turn_offset, tables.have.shape[0]
    x0, y0, inv_res, cell = p.x0, p.y0, p.inv_res, p.closed_cell
    gx, gy, gth = p.gx, p.gy, p.gth
    tol2, heading_tol, weight = p.tol2, p.heading_tol, p.weight
    shot_range2, s, beta = p.shot_range2, p.step, p.beta
    start_th, dtheta, radius, substep = p.start_heading, p.dtheta, p.radius, p.substep
    origin_r, origin_c = p.origin_row, p.origin_col
    blocked, cost_flat, bin_table = maps.blocked, maps.cost, maps.bin_table
    offsets, tab_have, tab_rows, tab_cols = tables.offsets, tables.have, tables.rows, tables.cols
    tab_ends, tab_bins, tab_fallback = tables.ends, tables.bins, tables.fallback
    nx, ny, ng, nturn, nrow, ncol = nodes.x, nodes.y, nodes.g, nodes.turns, nodes.row, nodes.col
    nparent, nprim, nkey, ngoal = nodes.parent, nodes.primitive, nodes.key, nodes.is_goal
    hf, hc, hnode = open_list.f, open_list.count, open_list.node
    key_state, best_g, expanded = closed.state, closed.best_g, progress.expanded
    flat_base = (pad - 1) * (pad_w + 1)
    # the cost-to-go's arrays, taken out of their tuples once (not per lookup)
    full_where, full_dist = h.full.where, h.full.dist
    terrain_where, terrain_dist = h.terrain.where, h.terrain.dist
    zero_terrain, phi = h.zero_terrain, h.phi
    n_nodes, heap_size = progress.n_nodes[0], progress.heap_size[0]
    counter, n_exp = progress.counter[0], progress.n_expanded[0]
    best_goal = progress.best_goal[0]
    kinds = np.empty(3, np.int64)
    lengths = np.empty(3)
    shot_buf = np.empty((1024, 3))
    hit = np.empty(3, np.bool_)
    status = EXHAUSTED
    capacity = nx.shape[0]
    n_keys = key_state.shape[0]
    while heap_size > 0:
        if n_nodes + 4 > capacity:
            status = NEED_ROOM
            break
        if n_exp >= p.max_expansions:
            status = CAPPED
            break
        if n_exp >= stop_at:
            status = PAUSED
            break
        node, heap_size = heap_pop(hf, hc, hnode, heap_size)
        if ngoal[node]:
            progress.result[0] = node
            status = FOUND
            break
        key = nkey[node]
        if key_state[key] == 2:
            continue
        key_state[key] = 2
        expanded[n_exp] = node
        n_exp += 1
        x, y, n, g = nx[node], ny[node], nturn[node], ng[node]
        # --- try_shot
        if (x - gx) ** 2 + (y - gy) ** 2 <= shot_range2 and g + distance(x - gx, y - gy) \
                < best_goal:
            th = start_th + n * dtheta
            if has_gth:
                n_seg = dubins(x, y, th, gx, gy, gth, radius, kinds, lengths)
            else:
                n_seg = turn_then_straight(x, y, th, gx, gy, radius, kinds, lengths)
            if n_seg > 0:
                total = 0.0
                for i in range(n_seg):
                    total += lengths[i]
                if total < best_goal - g:
                    needed = 0
                    for i in range(n_seg):
                        if lengths[i] > 1e-12:
                            needed += max(1, math.ceil(lengths[i] / substep))
                    if needed > shot_buf.shape[0]:
                        shot_buf = np.empty((2 * needed, 3))
                    n_poses = sample_free(x, y, th, kinds, lengths, n_seg, radius,
                                          substep, shot_buf, p, offsets, blocked)
                    if n_poses > 0:
                        g_goal = g + shot_cost(x, y, th, shot_buf, n_poses, p, cost_flat)
                        if g_goal < best_goal:
                            best_goal = g_goal
                            j = n_nodes
                            n_nodes += 1
                            nx[j], ny[j], nturn[j], nrow[j], ncol[j] = gx, gy, n, -1, -1
                            ng[j], nparent[j], nprim[j], ngoal[j], nkey[j] = (
                                g_goal, node, SHOT, True, -1)
                            heap_size = heap_push(hf, hc, hnode, heap_size, g_goal, counter, j)
                            counter += 1
        # --- expand
        t = n + turn_offset
        if t < 0 or t >= n_tables:
            status = OUT_OF_TABLES
            break
        if not tab_have[t]:
            build_table(t, n, p, tables)
            tab_have[t] = True
        shift_r = y * inv_res - origin_r
        shift_c = x * inv_res - origin_c
        for j in range(3):
            hit[j] = False
            for q in range(m):
                r = np.int64(tab_rows[t, j, q] + shift_r)
                c = np.int64(tab_cols[t, j, q] + shift_c)
                if blocked[pad_w * r + c + flat_base]:
                    hit[j] = True
                    break
        r0, c0 = nrow[node], ncol[node]
        for j in range(3):
            if hit[j]:
                continue
            xn = x + tab_ends[t, j, 0]
            yn = y + tab_ends[t, j, 1]
            key = ((np.int64((yn - y0) / cell) * nx_closed + np.int64((xn - x0) / cell)) * n_bins
                   + tab_bins[t, j])
            if key < 0 or key >= n_keys:  # off the map: cannot happen for a free footprint
                continue
            if key_state[key] == 2:
                continue
            rn = np.int64((yn - y0) * inv_res)
            cn = np.int64((xn - x0) * inv_res)
            k = bin_table[(rn - r0 + reach) * bin_row + (cn - c0 + reach)]
            if k < 0:
                k = tab_fallback[t, j]
            cost = cost_flat[(k * H + rn) * W + cn]
            gn = g + s * (1.0 + cost * (1.0 + beta * cost))
            if (key_state[key] == 1 and gn >= best_g[key]) or gn >= best_goal:
                continue
            nn = n + (0, 1, -1)[j]
            goal = (xn - gx) ** 2 + (yn - gy) ** 2 <= tol2
            if goal and has_gth:
                goal = abs(angle_diff(start_th + nn * dtheta, gth)) <= heading_tol
            if goal:
                hn = 0.0
            else:
                hn = distance(xn - gx, yn - gy)
                if use_h:
                    flat = rn * W + cn
                    if full_where[flat] != -2 or not zero_terrain and terrain_where[flat] != -2:
                        settle_cell(flat, h)
                    h_grid, h_terr = bound_of(flat, full_dist, terrain_dist, zero_terrain, phi)
                    hn = max(h_grid, hn + h_terr)
                    if hn == np.inf:
                        continue
            key_state[key] = 1
            best_g[key] = gn
            if goal:
                best_goal = gn
            i = n_nodes
            n_nodes += 1
            nx[i], ny[i], nturn[i], nrow[i], ncol[i] = xn, yn, nn, rn, cn
            ng[i], nparent[i], nprim[i], ngoal[i], nkey[i] = gn, node, j, goal, key
            heap_size = heap_push(hf, hc, hnode, heap_size, gn + weight * hn, counter, i)
            counter += 1
    progress.n_nodes[0], progress.heap_size[0] = n_nodes, heap_size
    progress.counter[0], progress.n_expanded[0] = counter, n_exp
    progress.best_goal[0] = best_goal
    return status
