"""MPPI's sampling, rollout and critics compiled with numba (``MPPIController(backend=
"compiled")``, the default).

Each kernel is a transcription of the numpy reference (``backend="numpy"``), with the same
float32 operations in the same order, so that both backends compute the same costs to the
bit and return the same commands (``tests/test_mppi_compiled.py`` checks it call by call):

- :func:`sample_rollouts` — :func:`~dgt_lib.navigation.control.sampling.sample_controls`
  (clipped, integrated noise around the warm start),
  :func:`~dgt_lib.navigation.control.sampling.vehicle_response` (``scipy.signal.lfilter``'s
  first-order lag, in its order of operations) and the yaw part of
  :func:`~dgt_lib.navigation.control.bicycle.rollout_unicycle`;
- :func:`project_on_path` — the positions' cumulative sums and
  :func:`~dgt_lib.navigation.control.critics.path_errors`' nearest-point projection (the
  reference's ``einsum`` score |w|² − 2 p·w, then its first minimum);
- :func:`occupancy_cost` — :func:`~dgt_lib.navigation.control.critics.occupancy_critic`
  with numpy's reductions along time: sums in order over the steps, the collision
  fraction in float64;
- :func:`terrain_cost` — :func:`~dgt_lib.navigation.control.critics.terrain_critic`, the
  directional costmap read at each step's body centre and heading, summed in order.

:func:`sampled_costs` strings them together as the reference's steps 1–3. What stays in
numpy is what numpy does in SIMD and a scalar loop would do differently in the last bit:
the cosines and sines (numpy's float32 ``cos``/``sin`` are not the C library's), the
path critics' means and the weighting. Every kernel loops over time outside and samples
inside, along the arrays' rows, without temporaries: one pass where numpy makes dozens.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.control.critics import constraint_critic, path_terms, total_cost

F32 = np.float32


@njit(cache=True)
def sample_rollouts(ev, ew, nom_v, nom_w, last_v, dt, accel_std, decel_max, accel_max,
                    v_min, v_max, w_noise, inv_r_min, w_max, b0, a1, z0, yaw0,
                    v, w, v_act, w_act, yaw, mid, breakaway):
    """Sampled commands and the vehicle's response, all ``(T, B)`` float32, in place.

    ``ev``, ``ew``: standard normal noise (column 0 zero: the warm start);
    ``nom_v``, ``nom_w``: (T,) the warm start; every scalar a float32 as the reference
    casts it (``w_noise`` = σ_ω̇·dt, ``inv_r_min`` = 1/r_min, ``b0`` = α and ``a1`` =
    α − 1 the lag filter's coefficients, ``z0`` = (1 − α)·speed its state, ``breakaway``
    the command below which the achieved speed is 0; the filter's state runs on).
    Writes the commands ``v``, ``w``, the achieved ``v_act``, ``w_act``, the yaw at the
    end of each step and the step's midpoint yaw ``mid`` (positions need numpy's cos).
    """
    T, B = ev.shape
    zero, one, half = F32(0.0), F32(1.0), F32(0.5)
    v_floor = F32(0.05)
    cum_v = np.empty(B, np.float32)
    cum_w = np.empty(B, np.float32)
    lag = np.full(B, z0, np.float32)
    cum_yaw = np.empty(B, np.float32)
    for t in range(T):
        prev = last_v if t == 0 else nom_v[t - 1]
        accel = (nom_v[t] - prev) / dt
        for b in range(B):
            inc = ev[t, b] * accel_std
            inc = inc + accel
            inc = min(max(inc, -decel_max), accel_max) * dt
            cum_v[b] = inc if t == 0 else cum_v[b] + inc
            vv = min(max(cum_v[b] + last_v, v_min), v_max)
            inc_w = ew[t, b] * w_noise
            cum_w[b] = inc_w if t == 0 else cum_w[b] + inc_w
            ww = cum_w[b] + nom_w[t]
            bound = min(abs(vv) * inv_r_min, w_max)
            ww = max(min(ww, bound), -bound)
            v[t, b] = vv
            w[t, b] = ww
            # scipy's lfilter, order 1: y = z + b0·x; z = x·b1 − y·a1 (b1 = 0)
            va = lag[b] + b0 * vv
            lag[b] = vv * zero - va * a1
            if abs(vv) < breakaway:
                va = zero
            sign = -one if vv < zero else one
            wa = ww * (va / (sign * max(abs(vv), v_floor)))
            v_act[t, b] = va
            w_act[t, b] = wa
            dyaw = wa * dt
            cum_yaw[b] = dyaw if t == 0 else cum_yaw[b] + dyaw
            psi = cum_yaw[b] + yaw0
            yaw[t, b] = psi
            mid[t, b] = psi - half * dyaw


@njit(cache=True)
def project_on_path(v_act, cos_mid, sin_mid, yaw, dt, first, every, wx, wy, tx, ty, s_win,
                    path_yaw, length, target_speed, two_decel, inv_target, x, y,
                    cross, angle_err, speed_err):
    """Rollout positions and their projection on the path window, in place.

    ``x``, ``y`` ``(T, B)``: Σ v̂·dt·cos/sin(mid) from the robot (the reference's
    cumulative sums). For every ``every``-th step from ``first`` (rows of the ``(T', B)``
    outputs): the nearest window point j (first minimum of |w_j|² − 2 p·w_j), the
    distance to the path ``cross`` [m] (lateral, plus any overshoot before its start or
    past its end), ``angle_err`` = ψ − ψ_path(j) [rad] and the speed error
    ``speed_err`` = (v̂ − v_ref)/v_target with v_ref = min(v_target, √(2·a·d_remaining)).
    Window arrays (M,) float32, relative to the robot; scalars float32.
    """
    T, B = v_act.shape
    M = wx.shape[0]
    zero = F32(0.0)
    m2 = F32(-2.0)
    wa = np.empty(M, np.float32)
    wb = np.empty(M, np.float32)
    wc = np.empty(M, np.float32)
    best = np.empty(B, np.float32)
    nearest = np.empty(B, np.int64)
    for k in range(M):
        wa[k] = m2 * wx[k]
        wb[k] = m2 * wy[k]
        wc[k] = wx[k] * wx[k] + wy[k] * wy[k]
    row = 0
    for t in range(T):
        for b in range(B):
            step = v_act[t, b] * dt
            dx = step * cos_mid[t, b]
            dy = step * sin_mid[t, b]
            x[t, b] = dx if t == 0 else x[t - 1, b] + dx
            y[t, b] = dy if t == 0 else y[t - 1, b] + dy
        if t < first or (t - first) % every != 0:
            continue
        for b in range(B):  # the first minimum over the window, samples innermost
            best[b] = (x[t, b] * wa[0] + y[t, b] * wb[0]) + wc[0]
            nearest[b] = 0
        for k in range(1, M):
            for b in range(B):
                score = (x[t, b] * wa[k] + y[t, b] * wb[k]) + wc[k]
                if score < best[b]:
                    best[b] = score
                    nearest[b] = k
        for b in range(B):
            px, py, j = x[t, b], y[t, b], nearest[b]
            ex, ey = px - wx[j], py - wy[j]
            lateral = ex * ty[j] - ey * tx[j]
            along = ex * tx[j] + ey * ty[j]
            s = s_win[j] + along
            beyond = max(-s, zero) + max(s - length, zero)
            cross[row, b] = np.sqrt(lateral * lateral + beyond * beyond)
            angle_err[row, b] = yaw[t, b] - path_yaw[j]
            remaining = max(length - s, zero)
            v_ref = min(target_speed, np.sqrt(two_decel * remaining))
            speed_err[row, b] = (v_act[t, b] - v_ref) * inv_target
        row += 1


@njit(cache=True)
def occupancy_cost(x, y, cos_yaw, sin_yaw, offsets, cell_hit, cell_near, ox, oy, inv_res,
                   w_collide, w_inflate, out):
    """Collision and inflation critics ``(B,)`` into ``out``, as the reference's
    :func:`~dgt_lib.navigation.control.critics.occupancy_critic`. Per footprint circle
    (``offsets`` [m] ahead of the pose) and step, the terms of the circle's cell (with the
    grid's occupied border ring):
    ``cell_hit`` (float64 1 where the clearance d < r_c, else 0) and ``cell_near``
    (float32 clip((r_i − d)/(r_i − r_c), 0, 1)). Collision = fraction of steps hit
    (summed in float64, as numpy's mean of booleans) + whether any step is; inflation
    = the mean of ``cell_near``. ``ox``, ``oy``: the robot's position relative to the
    grid origin [m]; scalars float32."""
    T, B = x.shape
    Hp, Wp = cell_near.shape
    zero, one = F32(0.0), F32(1.0)
    collide = np.zeros(B, np.float32)
    inflate = np.zeros(B, np.float32)
    hits = np.empty(B, np.float64)
    closeness = np.empty(B, np.float32)
    for off in offsets:
        shifted = off != zero
        hits[:] = 0.0  # numpy's sums along time, in order (0 + the first step's term is it)
        closeness[:] = zero
        for t in range(T):
            for b in range(B):
                cx = x[t, b] + ox
                cy = y[t, b] + oy
                if shifted:
                    cx = cx + off * cos_yaw[t, b]
                    cy = cy + off * sin_yaw[t, b]
                # clipped ≥ 0, so unsigned: numba then skips negative-index wrapping
                col = np.uint32(min(max(np.floor(cx * inv_res) + one, zero), F32(Wp - 1)))
                row = np.uint32(min(max(np.floor(cy * inv_res) + one, zero), F32(Hp - 1)))
                hits[b] += cell_hit[row, col]
                closeness[b] += cell_near[row, col]
        for b in range(B):
            collide[b] = F32(np.float64(collide[b]) + hits[b] / T)
            if hits[b] > 0.0:
                collide[b] += one
            inflate[b] += closeness[b] / F32(T)
    for b in range(B):
        out[b] = w_collide * collide[b] + w_inflate * inflate[b]


@njit(cache=True)
def terrain_cost(x, y, yaw, cos_yaw, sin_yaw, table, ox, oy, ahead, inv_res, bins_per_rad,
                 weight, out):
    """The terrain critic ``(B,)`` into ``out``, as the reference's
    :func:`~dgt_lib.navigation.control.critics.terrain_critic`: per step, the per-cell
    term ``table`` ``(K, H, W)`` (C(1 + β_c C), float32) at the body centre, ``ahead``
    [m] along the heading from the pose (its cell clamped to the grid), in the layer
    k = ⌊ψ·K/2π + ½⌋ mod K (``bins_per_rad`` = K/2π); summed over the steps in order,
    divided by T, times ``weight``. ``ox``, ``oy``: the robot relative to the grid origin
    [m]; scalars float32."""
    T, B = x.shape
    K, H, W = table.shape
    zero, half = F32(0.0), F32(0.5)
    acc = np.zeros(B, np.float32)
    for t in range(T):
        for b in range(B):
            cx = x[t, b] + ox
            cy = y[t, b] + oy
            cx = cx + ahead * cos_yaw[t, b]
            cy = cy + ahead * sin_yaw[t, b]
            col = np.int64(min(max(np.floor(cx * inv_res), zero), F32(W - 1)))
            row = np.int64(min(max(np.floor(cy * inv_res), zero), F32(H - 1)))
            k = np.int64(np.floor(yaw[t, b] * bins_per_rad + half)) % K
            acc[b] += table[k, row, col]
    for b in range(B):
        out[b] = weight * (acc[b] / F32(T))


def cell_terms(clearance: np.ndarray, cfg: MPPIConfig) -> tuple[np.ndarray, np.ndarray]:
    """The occupancy critic's per-cell terms for :func:`occupancy_cost`, from the
    clearance field d [m]: float64 [d < r_c] and float32 clip((r_i − d)/(r_i − r_c), 0, 1)."""
    r_c, r_i = F32(cfg.collision_radius_m), F32(cfg.inflation_radius_m)
    return ((clearance < r_c).astype(np.float64),
            np.clip((r_i - clearance) / (r_i - r_c), 0.0, 1.0))


def sampled_costs(ev: np.ndarray, ew: np.ndarray, nominal: np.ndarray, last_v: float,
                  speed: float, pose: tuple[float, float, float],
                  window: tuple[np.ndarray, ...], length_m: float,
                  goal_xy: tuple[float, float] | None, cfg: MPPIConfig,
                  min_turn_radius_m: float, alpha: float,
                  cells: tuple[tuple[np.ndarray, np.ndarray], GridSpec] | None,
                  v: np.ndarray, w: np.ndarray,
                  terrain: tuple[np.ndarray, float] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """MPPI's steps 1–3 with the kernels: the sampled commands ``v``, ``w`` ``(T, B)``
    (written in place) and their costs S ``(B,)``, as ``MPPIController._sampled_costs``.
    ``ev``, ``ew``: the noise; ``nominal`` ``(T, 2)`` the warm start; ``pose`` (x0, y0,
    yaw0); ``window`` and ``length_m`` the path near the robot; ``goal_xy`` the goal
    relative to the robot when the goal critic is on; ``cells`` (:func:`cell_terms`, grid)
    when the occupancy critic is; ``terrain`` (the critic's table, the body centre's
    distance ahead of the pose [m]) when the terrain critic is (on the same grid)."""
    x0, y0, yaw0 = pose
    v_act, w_act, yaw, mid = (np.empty_like(v) for _ in range(4))
    a = alpha
    sample_rollouts(
        ev, ew, nominal[:, 0], nominal[:, 1], F32(last_v), F32(cfg.model_dt),
        F32(cfg.accel_std), F32(cfg.decel_max), F32(cfg.accel_max), F32(cfg.v_min),
        F32(cfg.v_max), F32(cfg.w_rate_std * cfg.model_dt), F32(1.0 / min_turn_radius_m),
        F32(cfg.w_max), F32(a), F32(a - 1.0), F32((1.0 - a) * speed), F32(yaw0), v, w, v_act,
        w_act, yaw, mid, F32(cfg.breakaway_speed_mps))
    x, y = np.empty_like(v), np.empty_like(v)
    first, every = cfg.path_point_step - 1, cfg.path_point_step
    scored = (cfg.time_steps - first + every - 1) // every
    cross, angle_err, speed_err = (np.empty((scored, cfg.batch_size), F32) for _ in range(3))
    project_on_path(
        v_act, np.cos(mid), np.sin(mid), yaw, F32(cfg.model_dt), first, every, *window,
        F32(length_m), F32(cfg.target_speed), F32(2.0 * cfg.goal_decel),
        F32(1.0 / cfg.target_speed), x, y, cross, angle_err, speed_err)
    sel = slice(first, None, every)
    cost = total_cost(path_terms(cross, angle_err, speed_err, x[sel], y[sel], goal_xy, cfg))
    if cells is not None:
        (cell_hit, cell_near), grid = cells
        cos_yaw, sin_yaw = np.cos(yaw), np.sin(yaw)
        ox, oy = F32(x0 - grid.origin_xy[0]), F32(y0 - grid.origin_xy[1])
        occupancy = np.empty_like(cost)
        occupancy_cost(
            x, y, cos_yaw, sin_yaw, np.array(cfg.footprint_offsets_m, F32), cell_hit,
            cell_near, ox, oy, F32(1.0 / grid.resolution), F32(cfg.collision_weight),
            F32(cfg.inflation_weight), occupancy)
        cost += occupancy
        if terrain is not None:
            table, ahead = terrain
            paid = np.empty_like(cost)
            terrain_cost(x, y, yaw, cos_yaw, sin_yaw, table, ox, oy, F32(ahead),
                         F32(1.0 / grid.resolution),
                         F32(table.shape[0] / (2.0 * np.pi)), F32(cfg.terrain_weight), paid)
            cost += paid
    cost += constraint_critic(v_act, w_act, cfg)
    return v, w, cost
