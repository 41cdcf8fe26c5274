"""Locomotion labels (paper: Methodology → Locomotion, Self-Supervised Label Generation).

Locomotion measures how closely the realised motion matched the commanded
motion u over an interval Δt; the traversability cost is C = 1 − L. It is
applied in a sliding window over each run, giving the time-indexed label L_v(t)
that is paired with the patch cut at the same time.

Choices made here (the paper leaves them open):

- Displacement ‖Δx‖ is *planar* (x, y): a 3-D displacement would reward
  climbing, since the same ground speed on a slope covers more 3-D distance.
- The window is *centred* on t and 1.0 s long by default: at u = 5 m/s it spans
  about 5 m, i.e. ±2.5 m, inside the ±4.4 m the patch at t reaches forward and
  back, so the label describes the terrain in that patch; it is long enough to
  average out the speed controller's ripple and the position sampling, short
  enough to localise a hard spot to a vehicle length. Near the run's start and
  end the window is shifted (not shrunk) to stay inside the run; a run shorter
  than the window uses the whole run.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

TARGET_SPEED_MPS = 5.0
"""u [m/s]: the speed the PID controller holds during data collection (paper: Locomotion)."""
SIGMA = 1.0 / 3.0
"""σ of the locomotion kernel (paper: Locomotion, following the terramechanics reference)."""
WINDOW_S = 1.0
"""Default sliding-window length [s] for :func:`locomotion_signal` (see module docstring)."""
MAX_ANGULAR_RATE_DPS = 100.0
"""A sample turning faster than this [°/s] is a simulator glitch: not valid, so no label or
patch is taken at it and no onboard frame is mapped (the pre-filtering of the paper's LaTeX
source, a passage its published text leaves out)."""


def locomotion(displacement_m, dt_s, u: float = TARGET_SPEED_MPS, sigma: float = SIGMA):
    """Locomotion L ∈ [0, 1] of a displacement over an interval (paper, Eq. locomotion):

        L = exp( −1/(2σ²) · ((u·Δt − ‖Δx‖) / (u·Δt))² )

    displacement_m: ‖Δx‖ [m], any shape; dt_s: Δt [s] (> 0), broadcastable;
    u: commanded speed [m/s], a number or broadcastable (a drive log's varies);
    sigma: kernel width (dimensionless).
    Full speed gives 1, standing still exp(−1/(2σ²)) = exp(−4.5) ≈ 0.011 for σ = 1/3.
    The formula is symmetric in the speed ratio: driving *faster* than u (e.g.
    rolling downhill) also lowers L, exactly as in the paper.
    """
    d = np.asarray(displacement_m, dtype=np.float64)
    dt = np.asarray(dt_s, dtype=np.float64)
    if not np.all(np.asarray(u) > 0) or not sigma > 0:
        raise ValueError(f"u and sigma must be > 0, got u={u}, sigma={sigma}")
    if np.any(dt <= 0):
        raise ValueError("dt_s must be > 0")
    if np.any(d < 0):
        raise ValueError("displacement_m is a distance and must be ≥ 0")
    expected = u * dt
    return np.exp(-(((expected - d) / expected) ** 2) / (2.0 * sigma**2))


def locomotion_signal(times_s: np.ndarray, positions: np.ndarray, window_s: float = WINDOW_S,
                      u: float = TARGET_SPEED_MPS, sigma: float = SIGMA,
                      at_s: np.ndarray | None = None,
                      label: Callable[[np.ndarray, float], np.ndarray] | None = None
                      ) -> np.ndarray:
    """L_v(t) of one run from a centred sliding window, at every sample (or at ``at_s``).

    times_s: (T,) strictly increasing [s]; positions: (T, 2) or (T, 3) [m]
    (only x, y are used); at_s: optional (M,) query times [s], e.g. the times
    patches were cut at (clipped to the run). For time t the window is
    [t − w/2, t + w/2], shifted to lie inside [t_0, t_{T−1}] (the whole run if it
    is shorter than w); positions at the window ends are linearly interpolated,
    so Δt is exactly the window length. Returns (T,) or (M,) float64 L ∈ [0, 1].
    label: the locomotion of (‖Δx‖ [m], Δt [s]) applied to each window, e.g. a learner's
    own from notebook 02's exercise; None is :func:`locomotion` with ``u`` and ``sigma``.
    """
    t = np.asarray(times_s, dtype=np.float64)
    p = np.asarray(positions, dtype=np.float64)
    if t.ndim != 1 or len(t) < 2:
        raise ValueError(f"times_s must be (T,) with T ≥ 2, got shape {t.shape}")
    if p.ndim != 2 or p.shape[0] != len(t) or p.shape[1] not in (2, 3):
        raise ValueError(f"positions must be (T, 2) or (T, 3) with T = {len(t)}, got {p.shape}")
    if not np.all(np.diff(t) > 0):
        raise ValueError("times_s must be strictly increasing")
    if not window_s > 0:
        raise ValueError(f"window_s must be > 0, got {window_s}")
    query = t if at_s is None else np.asarray(at_s, dtype=np.float64)
    span = min(window_s, t[-1] - t[0])
    start = np.clip(query - 0.5 * span, t[0], t[-1] - span)
    end = start + span
    dx = np.interp(end, t, p[:, 0]) - np.interp(start, t, p[:, 0])
    dy = np.interp(end, t, p[:, 1]) - np.interp(start, t, p[:, 1])
    if label is not None:
        return label(np.hypot(dx, dy), span)
    return locomotion(np.hypot(dx, dy), span, u=u, sigma=sigma)


def mean_command(cmd_t: np.ndarray, cmd_v: np.ndarray, a: np.ndarray, b: np.ndarray
                 ) -> np.ndarray:
    """ū(a, b) = ∫ₐᵇ u dt / (b − a): the mean commanded speed [m/s] over each window
    [a, b] [s], each command ``cmd_v`` held from its time ``cmd_t`` until the next (the
    first also before it, the last after it)."""
    area = np.concatenate([[0.0], np.cumsum(cmd_v[:-1] * np.diff(cmd_t))])

    def integral(x: np.ndarray) -> np.ndarray:  # ∫ u dt from cmd_t[0] to x
        i = np.clip(np.searchsorted(cmd_t, x, side="right") - 1, 0, len(cmd_t) - 1)
        return area[i] + cmd_v[i] * (x - cmd_t[i])

    return (integral(b) - integral(a)) / np.maximum(b - a, 1e-9)
