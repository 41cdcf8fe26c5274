"""Reference solution to notebook 12's exercise: the mean commanded speed over a window."""

import numpy as np


def my_mean_command(cmd_t, cmd_v, a, b):
    """ū(a, b) [m/s] over each window [a, b] [s], each command held until the next."""
    cmd_t, cmd_v = np.asarray(cmd_t, float), np.asarray(cmd_v, float)
    out = []
    for lo, hi in zip(np.atleast_1d(a), np.atleast_1d(b), strict=True):
        edges = np.concatenate([[lo], cmd_t[(cmd_t > lo) & (cmd_t < hi)], [hi]])
        held = cmd_v[np.clip(np.searchsorted(cmd_t, edges[:-1], side="right") - 1, 0, None)]
        out.append(np.sum(held * np.diff(edges)) / (hi - lo))
    return np.array(out)
