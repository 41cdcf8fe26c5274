"""Reference solution to notebook 07's exercise: the Slope-Based baseline's L_sb(θ)."""

import numpy as np


def slope_locomotion(theta, theta0, theta_min, theta_max, p_u, p_d):
    """L_sb(θ) ∈ [0, 1] for forward slope θ [rad] (scalar or array); angles in radians."""
    theta = np.asarray(theta, dtype=np.float64)
    up = np.clip((theta - theta0) / (theta_max - theta0), 0.0, 1.0)
    down = np.clip((theta0 - theta) / (theta0 - theta_min), 0.0, 1.0)
    inside = (theta >= theta_min) & (theta <= theta_max)
    return np.where(inside, np.where(theta >= theta0, 1.0 - up**p_u, 1.0 - down**p_d), 0.0)
