"""Reference solution to notebook 10's exercise: the cells a new frame changed."""

import numpy as np


def changed_cells(old_channels, old_observed, new_channels, new_observed):
    """(H, W) bool: the cells whose observed flag or any channel differs between two BEV
    maps; every observed cell of the new one when there is no old one (None)."""
    if old_channels is None:
        return np.array(new_observed, dtype=bool)
    moved = np.any(np.asarray(old_channels) != np.asarray(new_channels), axis=0)
    return moved | (np.asarray(old_observed) != np.asarray(new_observed))
