"""MPPI's critics: the cost S_b of each sampled rollout b, term by term (paper: Controller
Integration; Nav2's critics). The numpy reference; the compiled backend computes the
same terms (:mod:`dgt_lib.navigation.control.mppi_compiled`).

Each critic returns its weighted term ``(B,)``; a term averages over the scored steps, so
each is of order 1 and compares directly with the temperature λ::

    S_b = w_path·path + w_angle·path_angle + w_speed·speed [+ w_goal·goal]
          [+ w_coll·collision + w_infl·inflation] [+ w_terr·terrain] + w_cons·constraint

Rollout positions are relative to the robot (float32 keeps its precision there);
``window`` is the path near the robot, :meth:`ReferencePath.window
<dgt_lib.navigation.control.reference_path.ReferencePath.window>`. The paper uses the
directional costmap for planning only; :func:`terrain_critic` (ours, off by default:
``terrain_weight`` 0) makes every rollout pay it too (docs/controller.md).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import distance_transform_edt

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.core.geometry import GridSpec

f32 = np.float32


def path_errors(x, y, yaw, v, window: tuple[np.ndarray, ...], length_m: float,
                cfg: MPPIConfig) -> tuple[np.ndarray, ...]:
    """Every ``path_point_step``-th rollout point ``(T', B)`` projected on the tangent of
    its nearest window point: the distance to the path [m] (lateral, plus any overshoot
    before its start or past its end), the yaw error ψ − ψ_path [rad], the speed error
    (v − v_ref)/v_target with v_ref = min(v_target, √(2·a_goal·d_remaining)), and the
    points' x, y [m]."""
    wx, wy, tx, ty, s_win, path_yaw = window
    sel = slice(cfg.path_point_step - 1, None, cfg.path_point_step)
    px, py = x[sel], y[sel]  # (T', B)
    # argmin_j |p − w_j|² = argmin_j (|w_j|² − 2 p·w_j): one product, no BLAS
    pts = np.stack([px, py], axis=-1)  # (T', B, 2)
    score = np.einsum("tbk,kw->tbw", pts, np.stack([-2.0 * wx, -2.0 * wy]))
    score += wx * wx + wy * wy
    j = score.argmin(axis=2)
    ex, ey = px - wx[j], py - wy[j]
    lateral = ex * ty[j] - ey * tx[j]
    along = ex * tx[j] + ey * ty[j]
    s = s_win[j] + along
    beyond = np.maximum(-s, 0.0) + np.maximum(s - f32(length_m), 0.0)
    cross = np.sqrt(lateral * lateral + beyond * beyond)
    remaining = np.maximum(f32(length_m) - s, 0.0)
    v_ref = np.minimum(f32(cfg.target_speed), np.sqrt(2.0 * cfg.goal_decel * remaining))
    speed_err = (v[sel] - v_ref) * f32(1.0 / cfg.target_speed)
    return cross, yaw[sel] - path_yaw[j], speed_err, px, py


def path_critic(cross: np.ndarray, cfg: MPPIConfig) -> np.ndarray:
    """w_path · mean_t d_t: the mean distance to the path [m]."""
    return cfg.path_weight * cross.mean(axis=0)


def path_angle_critic(angle_err: np.ndarray, cfg: MPPIConfig) -> np.ndarray:
    """w_angle · mean_t (1 − cos(ψ_t − ψ_path)): heading along the path."""
    align = 1.0 - np.cos(angle_err)
    return cfg.path_angle_weight * align.mean(axis=0)


def speed_critic(speed_err: np.ndarray, cfg: MPPIConfig) -> np.ndarray:
    """w_speed · mean_t ((v̂_t − v_ref)/v_target)²: the commanded 5 m/s, slowing for the
    goal."""
    return cfg.speed_weight * (speed_err * speed_err).mean(axis=0)


def goal_critic(px: np.ndarray, py: np.ndarray, goal_xy: tuple[float, float],
                cfg: MPPIConfig) -> np.ndarray:
    """w_goal · mean_t ‖p_t − goal‖ [m], ``goal_xy`` relative to the robot; on once the
    remaining path is shorter than ``goal_radius_m``."""
    gx, gy = goal_xy
    return cfg.goal_weight * np.hypot(px - f32(gx), py - f32(gy)).mean(0)


def path_terms(cross, angle_err, speed_err, px, py, goal_xy: tuple[float, float] | None,
               cfg: MPPIConfig) -> dict[str, np.ndarray]:
    """The path, path-angle, speed and (``goal_xy`` given) goal critics ``(B,)`` each, by
    name, from :func:`path_errors`."""
    terms = {"path": path_critic(cross, cfg), "path_angle": path_angle_critic(angle_err, cfg),
             "speed": speed_critic(speed_err, cfg)}
    if goal_xy is not None:
        terms["goal"] = goal_critic(px, py, goal_xy, cfg)
    return terms


def total_cost(terms: dict[str, np.ndarray]) -> np.ndarray:
    """S_b: the critics' terms summed in their order ``(B,)`` (a new array)."""
    values = iter(terms.values())
    cost = next(values).copy()
    for term in values:
        cost += term
    return cost


def clearance_field(occupancy: np.ndarray, grid: GridSpec) -> np.ndarray:
    """Distance [m] from each cell to the nearest occupied one, float32 ``(H + 2, W + 2)``.

    docs/ARCHITECTURE.md: 0 free, 1 occupied, 2 unobserved (occupied). A ring of occupied
    cells around the grid stands for everything off the map."""
    occupancy = np.asarray(occupancy)
    if occupancy.shape != grid.shape:
        raise ValueError(f"occupancy shape {occupancy.shape} ≠ grid shape {grid.shape}")
    free = np.zeros((grid.height + 2, grid.width + 2), bool)
    free[1:-1, 1:-1] = occupancy == 0
    return (distance_transform_edt(free) * grid.resolution).astype(np.float32)


def occupancy_critic(x, y, yaw, clearance: np.ndarray, offset_xy: tuple[float, float],
                     resolution_m: float, cfg: MPPIConfig) -> np.ndarray:
    """Collision and inflation critics ``(B,)``: per footprint circle (``cfg.
    footprint_offsets_m`` ahead of the pose) and step, the clearance d of its cell::

        collision = any_t [d_t < r_c] + mean_t [d_t < r_c]   (even when every sample
                    collides, the least bad one wins)
        inflation = mean_t clip((r_i − d_t)/(r_i − r_c), 0, 1)

    ``offset_xy``: the robot's position relative to the grid origin [m]; points off the
    grid land on the clearance field's zero border (occupied)."""
    Hp, Wp = clearance.shape
    inv = f32(1.0 / resolution_m)
    ox, oy = f32(offset_xy[0]), f32(offset_xy[1])
    r_c, r_i = f32(cfg.collision_radius_m), f32(cfg.inflation_radius_m)
    collide = np.zeros(x.shape[1], np.float32)
    inflate = np.zeros(x.shape[1], np.float32)
    for off in cfg.footprint_offsets_m:
        cx, cy = x + ox, y + oy
        if off != 0.0:
            cx += f32(off) * np.cos(yaw)
            cy += f32(off) * np.sin(yaw)
        col = np.clip(np.floor(cx * inv) + 1, 0, Wp - 1).astype(np.intp)
        row = np.clip(np.floor(cy * inv) + 1, 0, Hp - 1).astype(np.intp)
        d = clearance.ravel()[row * Wp + col]  # (T, B) clearance [m]
        hit = d < r_c
        collide += hit.mean(axis=0)
        collide += hit.any(axis=0)
        inflate += np.clip((r_i - d) / (r_i - r_c), 0.0, 1.0).mean(axis=0)
    return cfg.collision_weight * collide + cfg.inflation_weight * inflate


def constraint_critic(v, w, cfg: MPPIConfig) -> np.ndarray:
    """w_cons · (mean_t max(|v̂ω̂| − a_lat, 0)/a_lat [+ mean_t max(−v̂, 0)/v_target]):
    lateral acceleration above the limit, and reversing when it is allowed."""
    excess = np.maximum(np.abs(v * w) - f32(cfg.lateral_accel_max), 0.0)
    cost = (excess * f32(1.0 / cfg.lateral_accel_max)).mean(axis=0)
    if cfg.v_min < 0:
        cost += np.maximum(-v, 0.0).mean(axis=0) * f32(1.0 / cfg.target_speed)
    return cfg.constraint_weight * cost


def terrain_table(costmap: np.ndarray, cfg: MPPIConfig) -> np.ndarray:
    """The terrain critic's per-cell term, float32 ``(K, H, W)``: C(1 + β_c·C) of the
    directional costmap C ``(K, H, W)`` (layer k for heading θ_k = 2πk/K), the planner's
    amplification with β_c = ``cfg.terrain_beta``."""
    c = np.asarray(costmap, np.float32)
    if c.ndim != 3:
        raise ValueError(f"costmap must be (K, H, W), got shape {c.shape}")
    return c * (f32(1.0) + f32(cfg.terrain_beta) * c)


def heading_bins(yaw: np.ndarray, n_headings: int) -> np.ndarray:
    """k = ⌊ψ·K/2π + ½⌋ mod K in float32: the nearest of K headings θ_k = 2πk/K (paper:
    Directional Cost Lookup), for any yaw ψ [rad] (no wrapping needed)."""
    scaled = np.floor(yaw * f32(n_headings / (2.0 * np.pi)) + f32(0.5))
    return np.mod(scaled.astype(np.int64), n_headings)


def terrain_critic(x, y, yaw, table: np.ndarray, offset_xy: tuple[float, float],
                   resolution_m: float, ahead_m: float, cfg: MPPIConfig) -> np.ndarray:
    """w_terr · mean_t C_k(t)(p_t)(1 + β_c C): the cost a rollout pays on the directional
    costmap ``table`` (:func:`terrain_table`), read at its body centre p_t, ``ahead_m``
    (half the wheelbase) ahead of the rear-axle pose, in the layer of its heading ψ_t
    (:func:`heading_bins`); cells clamped to the grid as the planner's lookup. ``offset_xy``:
    the robot's position relative to the grid origin [m]. Returns ``(B,)``."""
    K, H, W = table.shape
    inv = f32(1.0 / resolution_m)
    cx = x + f32(offset_xy[0])
    cy = y + f32(offset_xy[1])
    cx += f32(ahead_m) * np.cos(yaw)
    cy += f32(ahead_m) * np.sin(yaw)
    col = np.clip(np.floor(cx * inv), 0, W - 1).astype(np.intp)
    row = np.clip(np.floor(cy * inv), 0, H - 1).astype(np.intp)
    cost = table.ravel()[(heading_bins(yaw, K) * H + row) * W + col]  # (T, B)
    return cfg.terrain_weight * cost.mean(axis=0)
