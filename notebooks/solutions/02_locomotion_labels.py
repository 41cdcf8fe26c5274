"""Reference solution to notebook 02's exercise: the locomotion label."""

import numpy as np

U_MPS = 5.0  # commanded speed u [m/s]
SIGMA = 1.0 / 3.0


def locomotion_label(displacement_m, dt_s):
    """L ∈ [0, 1] for ‖Δx‖ = displacement_m [m] over Δt = dt_s [s]; scalars or arrays."""
    expected = U_MPS * np.asarray(dt_s, dtype=np.float64)  # u·Δt [m]
    error = (expected - np.asarray(displacement_m, dtype=np.float64)) / expected
    return np.exp(-error**2 / (2.0 * SIGMA**2))
