"""What a driven trajectory cost: the directional costmap read along where the vehicle went.

A trial's success says whether the vehicle arrived; the driven cost says over what terrain.
Every logged position reads the costmap layer of the direction the vehicle moved in there
(paper: Directional Cost Lookup, k* = argmin_k |θ_k − θ|), so a truck that slid sideways
down a slope pays the slope's cross-slope cost, not its plan's. Used to compare controllers
on the same plans (``studies/controller_ablation.py``, ``studies/off_plan.py``).
"""

from __future__ import annotations

import numpy as np

from dgt_lib.core.geometry import GridSpec, nearest_heading_bin
from dgt_lib.evaluation.accuracy import cost_at

MIN_STEP_M = 0.05
"""Logged positions closer than this [m] to the previous counted one have no direction of
travel (a standing vehicle) and are skipped."""


def driven_cost(trajectory: np.ndarray, cost: np.ndarray, grid: GridSpec) -> float:
    """The mean cost C_k(x, y) ∈ [0, 1] of a (K, H, W) directional costmap along a
    trajectory (T, ≥ 3) of rows (t [s], x [m], y [m], …), each step read in the heading
    layer nearest its direction of motion at its end point. Cells off the map read the
    nearest edge cell. NaN when the vehicle never moved ``MIN_STEP_M``."""
    cost = np.asarray(cost)
    if cost.ndim != 3:
        raise ValueError(f"cost must be (K, H, W), got shape {cost.shape}")
    xy = np.asarray(trajectory, float)[:, 1:3]
    kept = [0]
    for i in range(1, len(xy)):  # thin out standing samples: their heading is noise
        if np.hypot(*(xy[i] - xy[kept[-1]])) >= MIN_STEP_M:
            kept.append(i)
    if len(kept) < 2:
        return float("nan")
    pts = xy[kept]
    step = np.diff(pts, axis=0)
    k = nearest_heading_bin(np.arctan2(step[:, 1], step[:, 0]), cost.shape[0])
    per_heading = cost_at(cost, grid, pts[1:], cost.shape[0])  # (N, K)
    return float(np.mean(per_heading[np.arange(len(k)), k]))
