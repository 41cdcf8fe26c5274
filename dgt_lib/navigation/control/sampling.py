"""MPPI's samples: noisy control sequences around the warm start, and what the vehicle
makes of them (paper: Controller Integration; the numpy reference of
:mod:`dgt_lib.navigation.control.mppi_compiled`'s ``sample_rollouts``).

Every array is float32 ``(T, B)`` — T horizon steps of ``model_dt`` [s], B sampled
sequences, sample 0 the warm start itself (zero noise). The positions follow from
:func:`dgt_lib.navigation.control.bicycle.rollout_unicycle`.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from dgt_lib.core.controller import MPPIConfig


def draw_noise(rng: np.random.Generator, eps_v: np.ndarray, eps_w: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """Standard normal noise into ``eps_v``, ``eps_w`` ``(T, B)`` (speeds, then yaw
    rates, float32), column 0 zero: sample 0 is the warm start."""
    rng.standard_normal(out=eps_v, dtype=np.float32)
    rng.standard_normal(out=eps_w, dtype=np.float32)
    eps_v[:, 0] = 0.0
    eps_w[:, 0] = 0.0
    return eps_v, eps_w


def sample_controls(eps_v: np.ndarray, eps_w: np.ndarray, nominal: np.ndarray, last_v: float,
                    cfg: MPPIConfig, min_turn_radius_m: float, v: np.ndarray, w: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Noisy (v [m/s], ω [rad/s]) sequences ``(T, B)`` around the warm start ``nominal``
    ``(T, 2)``, made feasible, written into ``v`` and ``w``::

        v_t = clip(v_last + Σ_{k≤t} clip(a_k + σ_a·ε_k, −a_dec, a_acc)·dt, v_min, v_max)
        ω_t = clip(ω*_t + Σ_{k≤t} σ_ω̇·dt·ε'_k, −ω̄_t, ω̄_t),  ω̄_t = min(ω_max, |v_t| / r_min)

    with a_k the warm start's own acceleration. Speeds are integrated accelerations (smooth
    ramps that can reach the target), yaw rates a random walk (a sample can hold a turn),
    and |ω| ≤ |v| / r_min is Nav2's Ackermann constraint.
    """
    dt = np.float32(cfg.model_dt)
    nominal_v = nominal[:, 0]
    accel = np.diff(nominal_v, prepend=np.float32(last_v)) / dt  # (T,)
    np.multiply(eps_v, np.float32(cfg.accel_std), out=v)
    v += accel[:, None]
    np.clip(v, -cfg.decel_max, cfg.accel_max, out=v)
    v *= dt
    np.cumsum(v, axis=0, out=v)
    v += np.float32(last_v)
    np.clip(v, cfg.v_min, cfg.v_max, out=v)
    np.multiply(eps_w, np.float32(cfg.w_rate_std * cfg.model_dt), out=w)
    np.cumsum(w, axis=0, out=w)
    w += nominal[:, 1:]
    bound = np.abs(v) * np.float32(1.0 / min_turn_radius_m)
    np.minimum(bound, np.float32(cfg.w_max), out=bound)
    np.minimum(w, bound, out=w)
    np.negative(bound, out=bound)
    np.maximum(w, bound, out=w)
    return v, w


def speed_lag_gain(cfg: MPPIConfig) -> float:
    """α = dt / (τ_v + dt), the gain of the speed loop's first-order lag per step."""
    return cfg.model_dt / (cfg.speed_time_constant_s + cfg.model_dt)


def vehicle_response(v: np.ndarray, w: np.ndarray, speed: float, alpha: float,
                     breakaway_mps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Speed and yaw rate ``(T, B)`` the vehicle achieves for commands (v, ω).

    The speed loop (``dgt_lib.world.speed_control.SpeedController`` in the simulator) is
    modelled as a first-order lag from the measured ``speed`` [m/s] (backward Euler)::

        v̂_t = α·v_t + (1 − α)·v̂_{t−1},   v̂_{−1} = measured speed

    run over all samples at once as an IIR filter along time (``lfilter``). Steering fixes
    the curvature κ = ω / v (the bicycle relation), so the yaw rate is ω̂ = v̂·ω / v.
    With ``breakaway_mps`` > 0 the vehicle stands still (v̂ = 0) at any step whose command
    is below it in magnitude: a crawl the truck does not drive is predicted as no motion.
    """
    zi = np.full((1, v.shape[1]), (1.0 - alpha) * speed, np.float32)
    v_act = lfilter(
        np.array([alpha], np.float32), np.array([1.0, alpha - 1.0], np.float32), v, axis=0,
        zi=zi)[0]
    if breakaway_mps > 0:
        v_act = np.where(np.abs(v) < np.float32(breakaway_mps), np.float32(0.0), v_act)
    v_safe = np.where(v < 0, np.float32(-1.0), np.float32(1.0)) * np.maximum(
        np.abs(v), np.float32(0.05))
    return v_act, w * (v_act / v_safe)
