"""Analytic shots: closed-form forward paths from a search node to the goal.

To a goal pose the shortest Dubins path (Dubins 1957); to a goal point the
shortest turn-then-straight (CS) path. A shot is sampled like a primitive and
priced like a sequence of primitives (:func:`shot_cost`).
"""

from __future__ import annotations

import math

import numpy as np

from dgt_lib.core.geometry import TWO_PI, GridSpec, nearest_heading_bin
from dgt_lib.navigation.planner.primitives import (
    arc_poses,
    distance,
    step_cost,
    travel_heading_bin,
)

SHOT_DISTANCE_M = 20.0
"""The search tries a shot from nodes this close to the goal [m] (with
``PlannerConfig.analytic_shot``)."""


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
    d = distance(dx, dy) / radius
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
        dist = distance(goal_xy[0] - cx, goal_xy[1] - cy)
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


def shot_poses(pose, goal_xy, goal_heading: float | None, radius: float, spacing_m: float,
               max_length_m: float) -> np.ndarray | None:
    """Poses (N, 3) of the analytic shot from ``pose`` to the goal, sampled at most
    ``spacing_m`` apart (collision not checked): Dubins to a goal pose, turn-then-
    straight to a goal point. None when there is none or it is not shorter than
    ``max_length_m``."""
    gx, gy = goal_xy
    if goal_heading is None:
        segments = turn_then_straight(pose, (gx, gy), radius)
        if segments is None:
            return None
    else:
        segments = dubins_path(pose, (gx, gy, goal_heading), radius)
    if sum(length for _, length in segments) >= max_length_m:
        return None
    return sample_segments(pose, segments, radius, spacing_m)


def shot_cost(pose, poses: np.ndarray, grid: GridSpec, cost_flat: np.ndarray, n_headings: int,
              step_m: float, beta: float, price=step_cost) -> float:
    """Σ g_edge along a shot, priced like primitives: pieces of arc length s = ``step_m``
    (the last one shorter, priced by its length), each at its end cell's directional
    cost C in ``cost_flat``, the flattened (K, H, W) costmap, by ``price`` (length, C, β)
    (:func:`.primitives.step_cost`, or the search's own edge cost)."""
    s = step_m
    seg = np.hypot(*np.diff(np.vstack([np.asarray(pose)[None, :3], poses])[:, :2], axis=0).T)
    arc = np.cumsum(seg)
    total_len = float(arc[-1])
    n_pieces = max(1, math.ceil(total_len / s - 1e-9))
    ends = np.minimum(np.arange(1, n_pieces + 1) * s, total_len)
    idx = np.minimum(np.searchsorted(arc, ends - 1e-9), len(poses) - 1)
    pts = np.vstack([np.asarray(pose)[None, :3], poses[idx]])
    rows, cols = grid.xy_to_cell(pts[:, 0], pts[:, 1])
    lengths = np.diff(np.concatenate([[0.0], ends]))
    H, W = grid.shape
    total = 0.0
    for i in range(n_pieces):
        dr, dc = int(rows[i + 1] - rows[i]), int(cols[i + 1] - cols[i])
        if dr == 0 and dc == 0:
            k = int(nearest_heading_bin(pts[i + 1, 2], n_headings))
        else:
            k = int(travel_heading_bin(dr, dc, n_headings))
        cost = cost_flat[(k * H + rows[i + 1]) * W + cols[i + 1]]
        total += price(float(lengths[i]), float(cost), beta)
    return total
