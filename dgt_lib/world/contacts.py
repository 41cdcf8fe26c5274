"""What the vehicle touches, read from MuJoCo's contact list after a step.

Each geom of the model has a kind (the simulator's list, by geom id): the world's (terrain,
a tree) sort below the vehicle's (chassis boxes, then the wheels fl, fr, rl, rr), so in a
contact pair the lower kind says what was touched and the higher one what touched it. The
list is read in plain Python: a step has a handful of contacts, and a dozen numpy calls on
arrays that small took a tenth of a control period's time (``benchmarks/bench_sim.py``).
"""

from __future__ import annotations

import mujoco
import numpy as np

OTHER, TERRAIN, TREE, CHASSIS, WHEEL = -1, 0, 1, 2, 3
"""Geom kinds; a wheel is ``WHEEL + index`` in the order fl, fr, rl, rr."""


def touching(data: mujoco.MjData, kinds: list[int]) -> tuple[np.ndarray, bool, bool]:
    """(wheel contacts (4,) bool, chassis on the terrain, vehicle on a tree) now: a wheel
    touches when it meets the terrain or a tree."""
    wheel, chassis_terrain, tree = [False] * 4, False, False
    for g1, g2 in (data.contact.geom[: data.ncon].tolist() if data.ncon else ()):
        world, car = sorted((kinds[g1], kinds[g2]))
        tree = tree or world == TREE
        chassis_terrain = chassis_terrain or (world == TERRAIN and car == CHASSIS)
        if world in (TERRAIN, TREE) and car >= WHEEL:
            wheel[car - WHEEL] = True
    return np.array(wheel), chassis_terrain, tree
