"""What the vehicle touches, read from MuJoCo's contact list after a step.

Each geom of the model has a kind (the simulator's list, by geom id): the world's (terrain,
a tree) sort below the vehicle's (chassis boxes, then the wheels fl, fr, rl, rr), so in a
contact pair the lower kind says what was touched and the higher one what touched it. The
list is read in plain Python, one table lookup per contact: a step has a handful of
contacts, and a dozen numpy calls on arrays that small took a tenth of a control period's
time (``benchmarks/bench_sim.py``).
"""

from __future__ import annotations

import mujoco
import numpy as np

OTHER, TERRAIN, TREE, CHASSIS, WHEEL = -1, 0, 1, 2, 3
"""Geom kinds; a wheel is ``WHEEL + index`` in the order fl, fr, rl, rr."""


CHASSIS_ON_TERRAIN, ON_TREE = 16, 32
"""Bits of a contact's meaning beside the wheels' (bit i: wheel i touches the world)."""


def _meaning(kind_a: int, kind_b: int) -> int:
    """What a contact between geoms of two kinds means, as bits: the lower kind says what
    was touched, the higher one what touched it; a wheel touches the terrain or a tree."""
    world, car = sorted((kind_a, kind_b))
    return ((1 << car - WHEEL if world in (TERRAIN, TREE) and car >= WHEEL else 0)
            | (CHASSIS_ON_TERRAIN if (world, car) == (TERRAIN, CHASSIS) else 0)
            | (ON_TREE if world == TREE else 0))


MEANING = {a: {b: _meaning(a, b) for b in range(OTHER, WHEEL + 4)}
           for a in range(OTHER, WHEEL + 4)}
""":func:`_meaning` of every pair of kinds, looked up per contact."""
_WHEELS = [np.array([m >> i & 1 for i in range(4)], bool) for m in range(16)]


def touching(data: mujoco.MjData, kinds: list[int]) -> tuple[np.ndarray, bool, bool]:
    """(wheel contacts (4,) bool, chassis on the terrain, vehicle on a tree) now, from the
    kind of each geom (by id)."""
    bits = 0
    if data.ncon:
        for g1, g2 in data.contact.geom[: data.ncon].tolist():
            bits |= MEANING[kinds[g1]][kinds[g2]]
    return _WHEELS[bits & 15].copy(), bool(bits & CHASSIS_ON_TERRAIN), bool(bits & ON_TREE)
