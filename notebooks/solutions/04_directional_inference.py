"""Reference solutions of notebook 04's exercises (paper: Directional Cost Lookup)."""

from __future__ import annotations

import numpy as np


def heading_bin(theta, n_headings):
    """k* = argmin_k |θ_k − θ'| on the circle, θ_k = 2πk/K: wrap θ' into [0, 2π), divide by
    the bin width 2π/K, round to the nearest integer, and wrap K back to 0."""
    width = 2 * np.pi / n_headings
    return np.mod(np.rint(np.mod(theta, 2 * np.pi) / width).astype(np.int64), n_headings)
