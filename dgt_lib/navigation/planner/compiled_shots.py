"""The analytic shots and their checks, compiled with numba for :mod:`.compiled`: Dubins and
turn-then-straight paths (:mod:`.shots`), their sampling with the footprint check of each
pose (``BlockedMap.collides``) and their price (``shots.shot_cost``), each with the same
floating-point operations in the same order as its Python reference. ``p`` is the query's
:class:`.compiled.SearchParams`."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from dgt_lib.navigation.planner.compiled_kernels import PI, TWO_PI, distance, mod2pi, nearest_bin


@njit(cache=True)
def dubins(sx, sy, sth, gx, gy, gth, radius, kinds, lengths):
    """shots.dubins_path: writes the best word's kinds (0 L, 1 S, 2 R) and lengths [m]."""
    dx, dy = gx - sx, gy - sy
    d = distance(dx, dy) / radius
    phi = math.atan2(dy, dx)
    a, b = mod2pi(sth - phi), mod2pi(gth - phi)
    sa, sb, ca, cb, cab = math.sin(a), math.sin(b), math.cos(a), math.cos(b), math.cos(a - b)
    best = np.inf
    p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)  # LSL
    if p2 >= 0:
        tmp = math.atan2(cb - ca, d + sa - sb)
        w0, w1, w2 = mod2pi(-a + tmp), math.sqrt(p2), mod2pi(b - tmp)
        total = w0 + w1 + w2
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 0, 1, 0
            lengths[0], lengths[1], lengths[2] = w0, w1, w2
    p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)  # RSR
    if p2 >= 0:
        tmp = math.atan2(ca - cb, d - sa + sb)
        w0, w1, w2 = mod2pi(a - tmp), math.sqrt(p2), mod2pi(-b + tmp)
        total = w0 + w1 + w2
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 2, 1, 2
            lengths[0], lengths[1], lengths[2] = w0, w1, w2
    p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)  # LSR
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        w0, w1, w2 = mod2pi(-a + tmp), p, mod2pi(-b + tmp)
        total = w0 + w1 + w2
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 0, 1, 2
            lengths[0], lengths[1], lengths[2] = w0, w1, w2
    p2 = -2 + d * d + 2 * cab - 2 * d * (sa + sb)  # RSL
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        w0, w1, w2 = mod2pi(a - tmp), p, mod2pi(b - tmp)
        total = w0 + w1 + w2
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 2, 1, 0
            lengths[0], lengths[1], lengths[2] = w0, w1, w2
    c = (6 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8  # RLR
    if abs(c) <= 1:
        p = mod2pi(TWO_PI - math.acos(c))
        t = mod2pi(a - math.atan2(ca - cb, d - sa + sb) + p / 2)
        w0, w1, w2 = t, p, mod2pi(a - b - t + p)
        total = w0 + w1 + w2
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 2, 0, 2
            lengths[0], lengths[1], lengths[2] = w0, w1, w2
    c = (6 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8  # LRL
    if abs(c) <= 1:
        p = mod2pi(TWO_PI - math.acos(c))
        t = mod2pi(-a - math.atan2(ca - cb, d + sa - sb) + p / 2)
        w0, w1, w2 = t, p, mod2pi(b - a - t + p)
        total = w0 + w1 + w2
        if total < best:
            best = total
            kinds[0], kinds[1], kinds[2] = 0, 2, 0
            lengths[0], lengths[1], lengths[2] = w0, w1, w2
    for i in range(3):
        lengths[i] = lengths[i] * radius
    return 3


@njit(cache=True)
def turn_then_straight(x, y, th, gx, gy, radius, kinds, lengths):
    """shots.turn_then_straight: 2 segments written, or 0 when there is no CS path."""
    found = False
    best = 0.0
    for side_i in range(2):
        side = 1.0 if side_i == 0 else -1.0
        cx, cy = x - side * radius * math.sin(th), y + side * radius * math.cos(th)
        dist = distance(gx - cx, gy - cy)
        if dist < radius:
            continue
        straight = math.sqrt(max(dist * dist - radius * radius, 0.0))
        phi = math.atan2(gy - cy, gx - cx)
        psi = phi - side * math.atan2(straight, radius)
        psi0 = th - side * PI / 2
        turn = mod2pi(side * (psi - psi0))
        if not found or turn * radius + straight < best:
            found = True
            best = turn * radius + straight
            kinds[0], kinds[1] = (0 if side_i == 0 else 2), 1
            lengths[0], lengths[1] = turn * radius, straight
    return 2 if found else 0


@njit(cache=True)
def sample_free(x, y, th, kinds, lengths, n_seg, radius, spacing, out, p, offsets, blocked):
    """shots.sample_segments into ``out`` (rows x, y, θ), each pose checked as it is
    sampled (``BlockedMap.collides``: floor((c − origin)/res) + pad, clipped): the number
    of poses, or −1 at the first whose footprint collides (the rest is not sampled)."""
    x0, y0, res = p.x0, p.y0, p.res
    pad, width = p.pad, p.pad_width
    height = blocked.shape[0] // width
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
                px, py, pth, cos_t, sin_t = x + t * cos_th, y + t * sin_th, th, cos_th, sin_th
            else:
                pth = th + kappa * t
                cos_t, sin_t = math.cos(pth), math.sin(pth)
                px, py = x + (sin_t - sin_th) / kappa, y - (cos_t - cos_th) / kappa
            for c in range(offsets.shape[0]):
                col = np.int64(math.floor((px + offsets[c] * cos_t - x0) / res)) + pad
                row = np.int64(math.floor((py + offsets[c] * sin_t - y0) / res)) + pad
                if blocked[min(max(row, 0), height - 1) * width + min(max(col, 0), width - 1)]:
                    return -1
            out[n_out, 0], out[n_out, 1], out[n_out, 2] = px, py, pth
            n_out += 1
        x, y, th = out[n_out - 1, 0], out[n_out - 1, 1], out[n_out - 1, 2]
    return n_out


@njit(cache=True)
def shot_cost(x, y, th, poses, n, p, cost_flat):
    """shots.shot_cost of poses[:n] from (x, y, θ)."""
    s, beta = p.step, p.beta
    x0, y0, res = p.x0, p.y0, p.res
    H, W, K = p.H, p.W, p.K
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
            k = nearest_bin(poses[idx, 2], K)
        else:
            k = nearest_bin(math.atan2(float(dr), float(dc)), K)
        cost = cost_flat[(k * H + row) * W + col]
        total += (end - prev_end) * (1.0 + cost * (1.0 + beta * cost))
        prev_end, prev_row, prev_col = end, row, col
    return total
