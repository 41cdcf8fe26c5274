"""Biased sampling: a share of MPPI's samples drawn around what a pure-pursuit tracker
would do, not around the warm start (ours; the paper's MPPI has none).

MPPI samples around its warm start, the last call's optimum. When that optimum has settled
on waiting — a truck at rest on a plan that turns at full lock at once, where too few
samples turn hard enough, soon enough — the samples stay near waiting too. An ancillary
controller gives the sampler a second centre that always moves along the plan. Following
Biased-MPPI (Trevisan & Alonso-Mora, *Biased-MPPI: Informing Sampling-Based Model Predictive
Control by Fusing Ancillary Controllers*, RA-L 2024), the last ``n`` of the B samples are
drawn around the rollout of pure pursuit along the reference path:

    v_t = min(v_{t−1} + a_max·dt, v_ref(s_t)),                         v_{−1} = the last command
    ω_t = clip(v_t · 2 sin α_t / l_d,  ±min(ω_max, v_t / r_min))

(α_t the bearing, from the rolled-out pose, of the path point ``l_d`` =
``ancillary_lookahead_m`` beyond the nearest one: the law
:class:`~dgt_lib.navigation.control.pure_pursuit.PurePursuit` steers the ground-truth drives
with; v_ref the speed critic's reference: the target speed, braked for the goal). The
samples keep their own noise; they are moved by shifting their noise (:func:`bias_noise`),
so both backends — which share the noise — score the same sequences. The weighting then
decides: a biased sample that costs less than waiting wins the weight, one that costs more
is ignored.
"""

from __future__ import annotations

import math

import numpy as np

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.navigation.control.reference_path import ReferencePath


def ancillary_count(cfg: MPPIConfig) -> int:
    """How many of the ``batch_size`` samples are biased: ``ancillary_fraction`` of them,
    rounded, never sample 0 (the warm start)."""
    return min(cfg.batch_size - 1, int(round(cfg.ancillary_fraction * cfg.batch_size)))


def pure_pursuit_rollout(ref: ReferencePath, i_robot: int, pose, last_v: float,
                         cfg: MPPIConfig, min_turn_radius_m: float) -> np.ndarray:
    """The (v [m/s], ω [rad/s]) sequence ``(T, 2)`` of pure pursuit along ``ref``, rolled
    out with the kinematic unicycle from ``pose`` (x, y, yaw) [m, m, rad] at progress
    ``i_robot`` and the last command ``last_v`` [m/s] (the module docstring's equations)."""
    dt, T = cfg.model_dt, cfg.time_steps
    pts, s = ref.points, ref.s
    ds = float(s[1] - s[0]) if len(s) > 1 else 1.0
    ahead = max(1, int(round(cfg.ancillary_lookahead_m / ds)))
    search = ahead + int(math.ceil(cfg.v_max * dt / ds)) + 2
    x, y, yaw = (float(p) for p in pose)
    v, i = max(float(last_v), 0.0), int(i_robot)
    out = np.empty((T, 2), np.float32)
    for t in range(T):
        hi = min(len(pts), i + search)
        i += int(np.argmin((pts[i:hi, 0] - x) ** 2 + (pts[i:hi, 1] - y) ** 2))
        remaining = ref.remaining_m(i)
        v_ref = min(cfg.target_speed, math.sqrt(2.0 * cfg.goal_decel * remaining))
        v = min(v + cfg.accel_max * dt, v_ref)
        tx, ty = pts[min(len(pts) - 1, i + ahead), :2]
        dx, dy = tx - x, ty - y
        alpha = math.atan2(dy, dx) - yaw
        kappa = 2.0 * math.sin(alpha) / max(math.hypot(dx, dy), 1e-3)
        bound = min(cfg.w_max, v / min_turn_radius_m)
        w = min(max(v * kappa, -bound), bound)
        out[t] = v, w
        yaw += w * dt
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
    return out


def bias_noise(eps_v: np.ndarray, eps_w: np.ndarray, nominal: np.ndarray, last_v: float,
               ancillary: np.ndarray, cfg: MPPIConfig, count: int) -> None:
    """Shift the noise of the last ``count`` samples, in place, so that
    :func:`~dgt_lib.navigation.control.sampling.sample_controls` draws them around
    ``ancillary`` ``(T, 2)`` instead of the warm start ``nominal`` ``(T, 2)``: the speed
    noise by the difference of the two sequences' accelerations / σ_a (exact while the
    acceleration stays within the limits), the yaw-rate noise by the difference of their
    step-to-step changes / (σ_ω̇·dt) (exact before the turning-radius clip)."""
    if count <= 0:
        return
    dt = np.float32(cfg.model_dt)
    acc_nom = np.diff(nominal[:, 0], prepend=np.float32(last_v)) / dt
    acc_anc = np.diff(ancillary[:, 0], prepend=np.float32(last_v)) / dt
    eps_v[:, -count:] += ((acc_anc - acc_nom) / np.float32(cfg.accel_std))[:, None]
    dw = np.diff(ancillary[:, 1] - nominal[:, 1], prepend=np.float32(0.0))
    eps_w[:, -count:] += (dw / np.float32(cfg.w_rate_std * cfg.model_dt))[:, None]
