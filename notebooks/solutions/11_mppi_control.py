"""Reference solution to notebook 11's exercise: MPPI's importance weights."""

import numpy as np


def my_mppi_weights(cost, temperature):
    """w_b = exp(−(S_b − min S)/λ) / η for the costs S (B,) and temperature λ."""
    cost = np.asarray(cost, dtype=np.float64)
    e = np.exp(-(cost - cost.min()) / temperature)
    return e / e.sum()
