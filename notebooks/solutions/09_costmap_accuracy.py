"""Reference solution to notebook 09's exercise: the directional contrast pairs."""

import numpy as np


def my_contrast_pairs(true_cost, valid, threshold):
    """(cells, k): two int arrays, one entry per opposite-heading pair that counts."""
    half = true_cost.shape[1] // 2
    ahead, behind = true_cost[:, :half], true_cost[:, half:]  # θ_k and θ_{k+K/2}, k < K/2
    counts = valid[:, :half] & valid[:, half:] & (np.abs(ahead - behind) > threshold)
    return np.nonzero(counts)
