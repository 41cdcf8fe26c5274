"""Small numba kernels of the compiled search (:mod:`.compiled`): numpy's angle semantics on
scalars, the turn tables of :class:`~.primitives.PrimitiveSet`, and the open list, a binary
heap ordered by (f, insertion count) — the order of Python's heap of (f, count, node)
tuples. Each transcribes its Python reference with the same floating-point operations in
the same order. ``p`` is the query's :class:`.compiled.SearchParams`. Beside them, the
exact distance transform of the footprint's blocked map (:class:`~.collision.BlockedMap`),
scipy's values to the bit."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * np.pi
PI = np.pi

# --- angles (numpy's semantics on scalars) ------------------------------------------------


@njit(cache=True)
def np_mod(a, b):
    """np.mod(a, b) for floats, b > 0: fmod, then shifted into b's sign (npy_divmod)."""
    m = np.fmod(a, b)
    if m != 0.0:
        if m < 0.0:
            m += b
    else:
        m = 0.0
    return m


@njit(cache=True)
def nearest_bin(theta, n):
    """geometry.nearest_heading_bin: rint(wrap(θ) / (2π/K)) mod K (rint: half to even)."""
    k = np.int64(np.rint(np_mod(theta, TWO_PI) / (TWO_PI / n)))
    return k % n


@njit(cache=True)
def angle_diff(a, b):
    d = np_mod(a - b + PI, TWO_PI) - PI
    if d == -PI:
        d = PI
    return d


@njit(cache=True)
def distance(dx, dy):
    """primitives.distance."""
    return math.sqrt(dx * dx + dy * dy)


@njit(cache=True)
def mod2pi(a):
    return a - TWO_PI * math.floor(a / TWO_PI)


# --- the turn tables (PrimitiveSet._build) ------------------------------------------------


@njit(cache=True)
def build_table(t, n, p, tables):
    """Fill row t of the turn tables (:class:`.compiled.TurnTables`) for turn count n:
    PrimitiveSet._build."""
    offsets, sub_t = tables.offsets, tables.sub_t
    tab_rows, tab_cols, tab_ends = tables.rows, tables.cols, tables.ends
    tab_bins, tab_fallback = tables.bins, tables.fallback
    th = p.start_heading + n * p.dtheta
    dtheta, inv_res = p.dtheta, p.inv_res
    n_sub, n_circ = p.n_substeps, p.n_circles
    kappas = (0.0, 1.0 / p.radius, -1.0 / p.radius)
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
    bin_width = TWO_PI / p.theta_bins
    for j in range(3):
        dn = (0, 1, -1)[j]
        tab_bins[t, j] = np.int64(math.floor(np_mod(th + dn * dtheta, TWO_PI) / bin_width + 0.5)
                                  ) % p.theta_bins
        tab_fallback[t, j] = nearest_bin(th + dn * dtheta / 2, p.K)


# --- the open list: a binary heap ordered by (f, insertion count) ---------------------------


@njit(cache=True)
def less(hf, hc, a, b):
    return hf[a] < hf[b] or (hf[a] == hf[b] and hc[a] < hc[b])


@njit(cache=True)
def heap_push(hf, hc, hn, size, f, count, node):
    i = size
    hf[i], hc[i], hn[i] = f, count, node
    while i > 0:
        parent = (i - 1) >> 1
        if less(hf, hc, i, parent):
            hf[i], hf[parent] = hf[parent], hf[i]
            hc[i], hc[parent] = hc[parent], hc[i]
            hn[i], hn[parent] = hn[parent], hn[i]
            i = parent
        else:
            break
    return size + 1


@njit(cache=True)
def heap_pop(hf, hc, hn, size):
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
        if right < size and less(hf, hc, right, left):
            least = right
        if less(hf, hc, least, i):
            hf[i], hf[least] = hf[least], hf[i]
            hc[i], hc[least] = hc[least], hc[i]
            hn[i], hn[least] = hn[least], hn[i]
            i = least
        else:
            break
    return top, size


# --- the blocked map's distance transform (BlockedMap) --------------------------------------


@njit(cache=True)
def squared_distances(occupied):
    """(H, W) the squared distance [cells²] from each cell centre to the nearest
    ``occupied`` one (∞ where none is): Felzenszwalb & Huttenlocher's exact transform, a
    column scan, then per row the lower envelope of the parabolas (c − q)² + g(q)². Every
    value is an integer held exactly, so its square root is scipy's
    ``distance_transform_edt`` of ``~occupied``, to the bit."""
    height, width = occupied.shape
    g = np.empty((height, width))  # distance along the column to the nearest occupied
    for r in range(height):
        for c in range(width):
            g[r, c] = 0.0 if occupied[r, c] else (g[r - 1, c] + 1.0 if r > 0 else np.inf)
    for r in range(height - 2, -1, -1):
        for c in range(width):
            g[r, c] = min(g[r, c], g[r + 1, c] + 1.0)
    out = np.empty((height, width))
    f = np.empty(width)  # g² of the row
    v = np.empty(width, np.int64)  # the envelope's parabolas (their columns) ...
    z = np.empty(width + 1)  # ... and where each one starts
    for r in range(height):
        for q in range(width):
            f[q] = g[r, q] * g[r, q]
        k = -1
        for q in range(width):
            if f[q] == np.inf:
                continue
            s = -np.inf
            while k >= 0:
                s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2.0 * (q - v[k]))
                if s > z[k]:
                    break
                k -= 1
            k += 1
            v[k], z[k], z[k + 1] = q, (s if k > 0 else -np.inf), np.inf
        if k < 0:
            out[r, :] = np.inf
            continue
        k = 0
        for q in range(width):
            while z[k + 1] < q:
                k += 1
            out[r, q] = (q - v[k]) * (q - v[k]) + f[v[k]]
    return out
