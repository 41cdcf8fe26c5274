"""The search's inner loops compiled with numba: one query's A* (``backend="compiled"``,
the default) and the grid Dijkstra of the 2D cost-to-go.

Each function is a line-by-line transcription of its pure-Python reference, with the same
floating-point operations in the same order, so that both backends expand the same nodes
in the same order and return the same plan (``tests/test_planner_exact.py``):

- :func:`search` — :meth:`HybridAStar.plan`'s loop with ``_Search.expand``,
  ``_Search.try_shot`` and ``_Search._is_goal`` (:mod:`.search`), the turn tables of
  :class:`~.primitives.PrimitiveSet`, ``BlockedMap.primitive_hits`` / ``collides``
  (:mod:`.collision`), and the analytic shots ``dubins_path``, ``turn_then_straight``,
  ``sample_segments`` and ``shot_cost`` (:mod:`.shots`);
- :func:`settle` / :func:`grid_dijkstra` — ``scipy.sparse.csgraph.dijkstra`` on the
  reversed 8-connected graphs of :class:`~.heuristics.CostToGo`, without building them,
  run only as far as the search needs (the same distances where it stops).

The open list is a binary heap of (f, insertion count) — the order of Python's heap of
(f, count, node) tuples; nodes, the closed set (a dense array over the closed-set cells)
and the turn tables live in arrays that :class:`CompiledSearch` allocates. numba compiles
these functions the first time they run in a fresh install (about 10–20 s on two cores)
and caches the machine code beside this file (``cache=True``), so later processes load
them in well under a second.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * np.pi
PI = np.pi

# search() return codes
FOUND, EXHAUSTED, CAPPED, PAUSED, OUT_OF_TABLES, NEED_ROOM = 0, 1, 2, 3, 4, 5

# slots of the integer and float parameter arrays of search()
(I_H, I_W, I_K, I_NX_CLOSED, I_BINS, I_REACH, I_HAS_GTH, I_USE_H, I_PAD_W, I_PAD, I_NSUB,
 I_NCIRC, I_MAX_EXP, I_TURN_OFFSET, I_ZERO_TERRAIN, I_N_I) = range(16)
(F_X0, F_Y0, F_INV_RES, F_CELL, F_GX, F_GY, F_GTH, F_TOL2, F_HEADING_TOL, F_WEIGHT,
 F_SHOT_RANGE2, F_STEP, F_BETA, F_START_TH, F_DTHETA, F_RADIUS, F_SUBSTEP, F_RES,
 F_ORIGIN_R, F_ORIGIN_C, F_PHI, F_N_F) = range(22)
# slots of the state arrays
S_NODES, S_HEAP, S_COUNTER, S_EXPANDED, S_RESULT, S_N_S = range(6)
SHOT = 3  # result.SHOT


# --- angles (numpy's semantics on scalars) ------------------------------------------------


@njit(cache=True)
def _mod(a, b):
    """np.mod(a, b) for floats, b > 0: fmod, then shifted into b's sign (npy_divmod)."""
    m = np.fmod(a, b)
    if m != 0.0:
        if m < 0.0:
            m += b
    else:
        m = 0.0
    return m


@njit(cache=True)
def _nearest_bin(theta, n):
    """geometry.nearest_heading_bin: rint(wrap(θ) / (2π/K)) mod K (rint: half to even)."""
    k = np.int64(np.rint(_mod(theta, TWO_PI) / (TWO_PI / n)))
    return k % n


@njit(cache=True)
def _angle_diff(a, b):
    d = _mod(a - b + PI, TWO_PI) - PI
    if d == -PI:
        d = PI
    return d


@njit(cache=True)
def _distance(dx, dy):
    """primitives.distance."""
    return math.sqrt(dx * dx + dy * dy)


@njit(cache=True)
def _mod2pi(a):
    return a - TWO_PI * math.floor(a / TWO_PI)


# --- the turn tables (PrimitiveSet._build) ------------------------------------------------


@njit(cache=True)
def _build_table(t, n, ip, fp, offsets, sub_t, tab_rows, tab_cols, tab_ends, tab_bins,
                 tab_fallback):
    th = fp[F_START_TH] + n * fp[F_DTHETA]
    dtheta, inv_res = fp[F_DTHETA], fp[F_INV_RES]
    n_sub, n_circ = ip[I_NSUB], ip[I_NCIRC]
    kappas = (0.0, 1.0 / fp[F_RADIUS], -1.0 / fp[F_RADIUS])
    sin_th, cos_th = math.sin(th), math.cos(th)
    for j in range(3):
        kappa = kappas[j]
        px = py = pth = 0.0
        for i in range(n_sub):
            ts = sub_t[i]
            if kappa == 0.0:
                px = ts * cos_th
                py = ts * sin_th
                pth = th
            else:
                pth = th + kappa * ts
                px = (math.sin(pth) - sin_th) / kappa
                py = -((math.cos(pth) - cos_th) / kappa)
            cos_p, sin_p = math.cos(pth), math.sin(pth)
            for c in range(n_circ):
                m = i * n_circ + c
                tab_rows[t, j, m] = (py + offsets[c] * sin_p) * inv_res
                tab_cols[t, j, m] = (px + offsets[c] * cos_p) * inv_res
        tab_ends[t, j, 0] = px
        tab_ends[t, j, 1] = py
    bin_width = TWO_PI / ip[I_BINS]
    for j in range(3):
        dn = (0, 1, -1)[j]
        tab_bins[t, j] = np.int64(math.floor(_mod(th + dn * dtheta, TWO_PI) / bin_width + 0.5)
                                  ) % ip[I_BINS]
        tab_fallback[t, j] = _nearest_bin(th + dn * dtheta / 2, ip[I_K])


# --- the open list: a binary heap ordered by (f, insertion count) ---------------------------


@njit(cache=True)
def _less(hf, hc, a, b):
    return hf[a] < hf[b] or (hf[a] == hf[b] and hc[a] < hc[b])


@njit(cache=True)
def _heap_push(hf, hc, hn, size, f, count, node):
    i = size
    hf[i], hc[i], hn[i] = f, count, node
    while i > 0:
        parent = (i - 1) >> 1
        if _less(hf, hc, i, parent):
            hf[i], hf[parent] = hf[parent], hf[i]
            hc[i], hc[parent] = hc[parent], hc[i]
            hn[i], hn[parent] = hn[parent], hn[i]
            i = parent
        else:
            break
    return size + 1


@njit(cache=True)
def _heap_pop(hf, hc, hn, size):
    """Remove the least entry; returns (its node, the new size)."""
    top = hn[0]
    size -= 1
    hf[0], hc[0], hn[0] = hf[size], hc[size], hn[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        least = left
        right = left + 1
        if right < size and _less(hf, hc, right, left):
            least = right
        if _less(hf, hc, least, i):
            hf[i], hf[least] = hf[least], hf[i]
            hc[i], hc[least] = hc[least], hc[i]
            hn[i], hn[least] = hn[least], hn[i]
            i = least
        else:
            break
    return top, size


# --- analytic shots (shots.py) ------------------------------------------------------------


@njit(cache=True)
def _dubins(sx, sy, sth, gx, gy, gth, radius, kinds, lengths):
    """shots.dubins_path: writes the best word's kinds (0 L, 1 S, 2 R) and lengths [m]."""
    dx, dy = gx - sx, gy - sy
    d = _distance(dx, dy) / radius
    phi = math.atan2(dy, dx)
    a, b = _mod2pi(sth - phi), _mod2pi(gth - phi)
    sa, sb, ca, cb, cab = math.sin(a), math.sin(b), math.cos(a), math.cos(b), math.cos(a - b)
    best = np.inf
    w = np.empty(3)
    p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)  # LSL
    if p2 >= 0:
        tmp = math.atan2(cb - ca, d + sa - sb)
        w[0], w[1], w[2] = _mod2pi(-a + tmp), math.sqrt(p2), _mod2pi(b - tmp)
        total = w[0] + w[1] + w[2]
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 0, 1, 0
            lengths[:] = w
    p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)  # RSR
    if p2 >= 0:
        tmp = math.atan2(ca - cb, d - sa + sb)
        w[0], w[1], w[2] = _mod2pi(a - tmp), math.sqrt(p2), _mod2pi(-b + tmp)
        total = w[0] + w[1] + w[2]
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 2, 1, 2
            lengths[:] = w
    p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)  # LSR
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        w[0], w[1], w[2] = _mod2pi(-a + tmp), p, _mod2pi(-b + tmp)
        total = w[0] + w[1] + w[2]
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 0, 1, 2
            lengths[:] = w
    p2 = -2 + d * d + 2 * cab - 2 * d * (sa + sb)  # RSL
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        w[0], w[1], w[2] = _mod2pi(a - tmp), p, _mod2pi(b - tmp)
        total = w[0] + w[1] + w[2]
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 2, 1, 0
            lengths[:] = w
    c = (6 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8  # RLR
    if abs(c) <= 1:
        p = _mod2pi(TWO_PI - math.acos(c))
        t = _mod2pi(a - math.atan2(ca - cb, d - sa + sb) + p / 2)
        w[0], w[1], w[2] = t, p, _mod2pi(a - b - t + p)
        total = w[0] + w[1] + w[2]
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 2, 0, 2
            lengths[:] = w
    c = (6 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8  # LRL
    if abs(c) <= 1:
        p = _mod2pi(TWO_PI - math.acos(c))
        t = _mod2pi(-a - math.atan2(ca - cb, d + sa - sb) + p / 2)
        w[0], w[1], w[2] = t, p, _mod2pi(b - a - t + p)
        total = w[0] + w[1] + w[2]
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 0, 2, 0
            lengths[:] = w
    for i in range(3):
        lengths[i] = lengths[i] * radius
    return 3


@njit(cache=True)
def _turn_then_straight(x, y, th, gx, gy, radius, kinds, lengths):
    """shots.turn_then_straight: 2 segments written, or 0 when there is no CS path."""
    found = False
    best = 0.0
    for side_i in range(2):
        side = 1.0 if side_i == 0 else -1.0
        cx, cy = x - side * radius * math.sin(th), y + side * radius * math.cos(th)
        dist = _distance(gx - cx, gy - cy)
        if dist < radius:
            continue
        straight = math.sqrt(max(dist * dist - radius * radius, 0.0))
        phi = math.atan2(gy - cy, gx - cx)
        psi = phi - side * math.atan2(straight, radius)
        psi0 = th - side * PI / 2
        turn = _mod2pi(side * (psi - psi0))
        if not found or turn * radius + straight < best:
            found = True
            best = turn * radius + straight
            kinds[0], kinds[1] = (0 if side_i == 0 else 2), 1
            lengths[0], lengths[1] = turn * radius, straight
    return 2 if found else 0


@njit(cache=True)
def _sample_segments(x, y, th, kinds, lengths, n_seg, radius, spacing, out):
    """shots.sample_segments into ``out`` (rows x, y, θ); returns the number of poses."""
    n_out = 0
    for s in range(n_seg):
        length = lengths[s]
        if length <= 1e-12:
            continue
        n = max(1, math.ceil(length / spacing))
        kind = kinds[s]
        kappa = 1.0 / radius if kind == 0 else (0.0 if kind == 1 else -1.0 / radius)
        cos_th, sin_th = math.cos(th), math.sin(th)
        for i in range(1, n + 1):
            t = length * i / n
            if kappa == 0.0:
                out[n_out, 0] = x + t * cos_th
                out[n_out, 1] = y + t * sin_th
                out[n_out, 2] = th
            else:
                th_t = th + kappa * t
                out[n_out, 0] = x + (math.sin(th_t) - sin_th) / kappa
                out[n_out, 1] = y - (math.cos(th_t) - cos_th) / kappa
                out[n_out, 2] = th_t
            n_out += 1
        x, y, th = out[n_out - 1, 0], out[n_out - 1, 1], out[n_out - 1, 2]
    return n_out


@njit(cache=True)
def _poses_collide(poses, n, ip, fp, offsets, blocked):
    """BlockedMap.collides(poses[:n]).any(): floor((c − origin)/res) + pad, clipped."""
    x0, y0, res = fp[F_X0], fp[F_Y0], fp[F_RES]
    pad, width = ip[I_PAD], ip[I_PAD_W]
    height = blocked.shape[0] // width
    for i in range(n):
        cos_t, sin_t = math.cos(poses[i, 2]), math.sin(poses[i, 2])
        for c in range(offsets.shape[0]):
            col = np.int64(math.floor((poses[i, 0] + offsets[c] * cos_t - x0) / res)) + pad
            row = np.int64(math.floor((poses[i, 1] + offsets[c] * sin_t - y0) / res)) + pad
            row = min(max(row, 0), height - 1)
            col = min(max(col, 0), width - 1)
            if blocked[row * width + col]:
                return True
    return False


@njit(cache=True)
def _shot_cost(x, y, th, poses, n, ip, fp, cost_flat):
    """shots.shot_cost of poses[:n] from (x, y, θ)."""
    s, beta = fp[F_STEP], fp[F_BETA]
    x0, y0, res = fp[F_X0], fp[F_Y0], fp[F_RES]
    H, W, K = ip[I_H], ip[I_W], ip[I_K]
    arc = np.empty(n)
    total_len = 0.0
    px, py = x, y
    for i in range(n):
        total_len += math.hypot(poses[i, 0] - px, poses[i, 1] - py)
        arc[i] = total_len
        px, py = poses[i, 0], poses[i, 1]
    n_pieces = max(1, math.ceil(total_len / s - 1e-9))
    total = 0.0
    prev_end = 0.0
    prev_row = np.int64(math.floor((y - y0) / res))
    prev_col = np.int64(math.floor((x - x0) / res))
    lo = 0
    for i in range(n_pieces):
        end = min((i + 1) * s, total_len)
        target = end - 1e-9
        while lo < n and arc[lo] < target:  # searchsorted, side="left" (ends increase)
            lo += 1
        idx = min(lo, n - 1)
        row = np.int64(math.floor((poses[idx, 1] - y0) / res))
        col = np.int64(math.floor((poses[idx, 0] - x0) / res))
        dr, dc = row - prev_row, col - prev_col
        if dr == 0 and dc == 0:
            k = _nearest_bin(poses[idx, 2], K)
        else:
            k = _nearest_bin(math.atan2(float(dr), float(dc)), K)
        cost = cost_flat[(k * H + row) * W + col]
        total += (end - prev_end) * (1.0 + cost * (1.0 + beta * cost))
        prev_end, prev_row, prev_col = end, row, col
    return total


# --- one query's search ---------------------------------------------------------------------


@njit(cache=True)
def search(ip, fp, blocked, cost_flat, bin_table, h_passable, h_moves, h_weights_full,
           h_weights_terrain, h_full, h_heap_full, h_where_full, h_size_full, h_terrain,
           h_heap_terrain, h_where_terrain, h_size_terrain, offsets, sub_t,
           tab_have, tab_rows, tab_cols, tab_ends, tab_bins, tab_fallback,
           nx, ny, ng, nturn, nrow, ncol, nparent, nprim, nkey, ngoal,
           hf, hc, hnode, key_state, best_g, expanded, state, best_goal_box, stop_at):
    """Run the A* loop of HybridAStar.plan until the goal is popped (FOUND, the goal node
    in state[S_RESULT]), the open list empties (EXHAUSTED), ``ip[I_MAX_EXP]`` nodes were
    expanded (CAPPED), ``stop_at`` expansions were reached (PAUSED: call again to go on)
    or a turn count leaves the tables (OUT_OF_TABLES), or before an expansion that might
    overflow the node arrays (NEED_ROOM: grow them all and call again)."""
    H, W, n_bins = ip[I_H], ip[I_W], ip[I_BINS]
    nx_closed, reach = ip[I_NX_CLOSED], ip[I_REACH]
    bin_row = 2 * reach + 1
    use_h, has_gth = ip[I_USE_H] != 0, ip[I_HAS_GTH] != 0
    zero_terrain, phi = ip[I_ZERO_TERRAIN] != 0, fp[F_PHI]
    pad_w, pad = ip[I_PAD_W], ip[I_PAD]
    m = ip[I_NSUB] * ip[I_NCIRC]
    turn_offset, n_tables = ip[I_TURN_OFFSET], tab_have.shape[0]
    x0, y0, inv_res, cell = fp[F_X0], fp[F_Y0], fp[F_INV_RES], fp[F_CELL]
    gx, gy, gth = fp[F_GX], fp[F_GY], fp[F_GTH]
    tol2, heading_tol, weight = fp[F_TOL2], fp[F_HEADING_TOL], fp[F_WEIGHT]
    shot_range2, s, beta = fp[F_SHOT_RANGE2], fp[F_STEP], fp[F_BETA]
    start_th, dtheta, radius, substep = fp[F_START_TH], fp[F_DTHETA], fp[F_RADIUS], fp[F_SUBSTEP]
    origin_r, origin_c = fp[F_ORIGIN_R], fp[F_ORIGIN_C]
    flat_base = (pad - 1) * (pad_w + 1)
    n_nodes, heap_size, counter, n_exp = (state[S_NODES], state[S_HEAP], state[S_COUNTER],
                                          state[S_EXPANDED])
    best_goal = best_goal_box[0]
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
        if n_exp >= ip[I_MAX_EXP]:
            status = CAPPED
            break
        if n_exp >= stop_at:
            status = PAUSED
            break
        node, heap_size = _heap_pop(hf, hc, hnode, heap_size)
        if ngoal[node]:
            state[S_RESULT] = node
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
        if (x - gx) ** 2 + (y - gy) ** 2 <= shot_range2 and g + _distance(x - gx, y - gy) \
                < best_goal:
            th = start_th + n * dtheta
            if has_gth:
                n_seg = _dubins(x, y, th, gx, gy, gth, radius, kinds, lengths)
            else:
                n_seg = _turn_then_straight(x, y, th, gx, gy, radius, kinds, lengths)
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
                    n_poses = _sample_segments(x, y, th, kinds, lengths, n_seg, radius,
                                               substep, shot_buf)
                    if n_poses > 0 and not _poses_collide(shot_buf, n_poses, ip, fp, offsets,
                                                          blocked):
                        g_goal = g + _shot_cost(x, y, th, shot_buf, n_poses, ip, fp, cost_flat)
                        if g_goal < best_goal:
                            best_goal = g_goal
                            j = n_nodes
                            n_nodes += 1
                            nx[j], ny[j], nturn[j], nrow[j], ncol[j] = gx, gy, n, -1, -1
                            ng[j], nparent[j], nprim[j], ngoal[j], nkey[j] = (
                                g_goal, node, SHOT, True, -1)
                            heap_size = _heap_push(hf, hc, hnode, heap_size, g_goal, counter, j)
                            counter += 1
        # --- expand
        t = n + turn_offset
        if t < 0 or t >= n_tables:
            status = OUT_OF_TABLES
            break
        if not tab_have[t]:
            _build_table(t, n, ip, fp, offsets, sub_t, tab_rows, tab_cols, tab_ends, tab_bins,
                         tab_fallback)
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
                goal = abs(_angle_diff(start_th + nn * dtheta, gth)) <= heading_tol
            if goal:
                hn = 0.0
            else:
                hn = _distance(xn - gx, yn - gy)
                if use_h:
                    h_grid, h_terr = _bounds_at(
                        rn * W + cn, H, W, phi, zero_terrain, h_passable, h_moves,
                        h_weights_full, h_weights_terrain, h_full, h_heap_full, h_where_full,
                        h_size_full, h_terrain, h_heap_terrain, h_where_terrain,
                        h_size_terrain)
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
            heap_size = _heap_push(hf, hc, hnode, heap_size, gn + weight * hn, counter, i)
            counter += 1
    state[S_NODES], state[S_HEAP], state[S_COUNTER], state[S_EXPANDED] = (
        n_nodes, heap_size, counter, n_exp)
    best_goal_box[0] = best_goal
    return status


# --- the 2D cost-to-go --------------------------------------------------------------------
#
# heuristics.CostToGo's two relaxations are Dijkstra runs from the goal's cells over the
# reversed 8-connected graph: the move u → v = u + moves[m] (both cells passable) costs
# weights[v, m] (∞: no such move). A run's state lives in four arrays (dist, heap, where,
# size) so that it can stop and go on: the compiled search settles cells only as it needs
# their bound (:func:`settle`), and a run taken to the end (:func:`grid_dijkstra`) gives
# every cell's. The heap is an indexed binary heap ordered by dist; each distance is the
# sum dist[v] + w that scipy's dijkstra forms on the same graph, so it is the same to the
# bit, however far a run went.


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
def _bounds_at(flat, height, width, phi, zero_terrain, passable, moves, w_full, w_terrain,
               d_full, heap_full, where_full, size_full,
               d_terrain, heap_terrain, where_terrain, size_terrain):
    """(φ·D, φ·D_c) at cell ``flat``, settling both runs as far as needed; with
    ``zero_terrain`` D_c is 0 wherever D is finite (CostToGo's shortcut)."""
    if where_full[flat] != -2:
        settle(flat, height, width, passable, w_full, moves, d_full, heap_full, where_full,
               size_full)
    h_full = phi * d_full[flat]
    if zero_terrain:
        return h_full, phi * (0.0 if d_full[flat] != np.inf else np.inf)
    if where_terrain[flat] != -2:
        settle(flat, height, width, passable, w_terrain, moves, d_terrain, heap_terrain,
               where_terrain, size_terrain)
    return h_full, phi * d_terrain[flat]
