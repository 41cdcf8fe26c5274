"""Terrain a vehicle cannot cross, from the world's TRUE heights — the rule that makes
Experiment 3's random queries ones where the costmap matters (ours; the paper draws its
random start–goal pairs without one).

A cell is a **hazard** for a vehicle when either

- its slope (steepest, of the true heights) exceeds the grade the vehicle's motors can
  hold, :attr:`~dgt_lib.core.vehicle_spec.VehicleSpec.max_climb_deg` (torque-limited), or
- it is a **crest the belly hits**: along one of four directions (x, y, both diagonals)
  the cell stands more than the vehicle's ground clearance above the chord between the
  points half a wheelbase before and after it (:func:`belly_relief`) — a ridge or bump
  that high-centres the vehicle between its axles.

A third test, :func:`bumper_sag`, is the front bumper digging into the far wall of a
ditch (the approach angle); the query rule does not apply it (``vehicle_hazards(...,
bumpers=True)`` does: docs/worlds.md, the ``eval_hazard`` world).

All are computed from the world generator's heights and the vehicle's specification only:
never from a learned costmap, the BEV, or any method's outcome. Experiment 3 marks the
cells that are a hazard for *any* of its vehicles (:func:`hazard_map`) and keeps a random
query only when the straight segment start → goal crosses at least
``ExperimentsConfig.eval_min_hazard_m`` of them (:meth:`HazardMap.length_m`): a planner that
ignores terrain cost (Binary) is then led across terrain some vehicle cannot cross.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from dgt_lib.core.geometry import GridSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.world.terrain import BUMPER_RAISE_M
from dgt_lib.world.worlds import World

_DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))  # (row, col) steps: x, y, both diagonals


def belly_relief(heights: np.ndarray, resolution_m: float, half_span_m: float) -> np.ndarray:
    """(H, W) [m]: how far each cell stands above the chord between the cells
    ``half_span_m`` before and after it, the most over four directions (x, y, both
    diagonals; the span rounded to whole cells, at least one). Heights beyond the map
    edge repeat the edge."""
    h = np.asarray(heights, np.float64)
    rows, cols = h.shape
    out = np.full(h.shape, -np.inf)
    for dr, dc in _DIRECTIONS:
        n = max(1, int(round(half_span_m / (resolution_m * np.hypot(dr, dc)))))
        p = n  # padding: n cells in each direction
        padded = np.pad(h, p, mode="edge")
        ahead = padded[p + n * dr:p + n * dr + rows, p + n * dc:p + n * dc + cols]
        behind = padded[p - n * dr:p - n * dr + rows, p - n * dc:p - n * dc + cols]
        out = np.maximum(out, h - 0.5 * (ahead + behind))
    return out


_HEADINGS = tuple((s * dr, s * dc) for dr, dc in _DIRECTIONS for s in (1, -1))


def bumper_sag(heights: np.ndarray, resolution_m: float, wheelbase_m: float,
               overhang_m: float) -> np.ndarray:
    """(H, W) [m]: with the front wheels on a cell and the rear wheels ``wheelbase_m``
    behind, how far the ground ``overhang_m`` ahead rises above the line through the two
    wheel contacts, extended forward — the most over eight headings (x, y, diagonals,
    both ways; lengths rounded to whole cells, at least one). Zero on any plane, > 0 in a
    sag: above the bumper's height, the bumper digs into the far wall of a ditch.
    Heights beyond the map edge repeat the edge."""
    h = np.asarray(heights, np.float64)
    rows, cols = h.shape
    out = np.full(h.shape, -np.inf)
    for dr, dc in _HEADINGS:
        step = resolution_m * np.hypot(dr, dc)
        nl = max(1, int(round(wheelbase_m / step)))
        no = max(1, int(round(overhang_m / step)))
        p = max(nl, no)
        padded = np.pad(h, p, mode="edge")
        ahead = padded[p + no * dr:p + no * dr + rows, p + no * dc:p + no * dc + cols]
        rear = padded[p - nl * dr:p - nl * dr + rows, p - nl * dc:p - nl * dc + cols]
        out = np.maximum(out, ahead - (h + (h - rear) * (no / nl)))
    return out


def vehicle_hazards(world: World, vehicle: str, *, bumpers: bool = False) -> np.ndarray:
    """(H, W) bool on ``world.grid``: the cells ``vehicle`` cannot cross (the module's
    rule: slope above its max climb, or a crest higher than its ground clearance above
    the chord of half its wheelbase each way; with ``bumpers``, also a sag where the
    ground ahead rises above its front bumper, :func:`bumper_sag`)."""
    spec = get_vehicle(vehicle)
    too_steep = world.slope_deg() > spec.max_climb_deg
    crest = belly_relief(world.heights, world.grid.resolution,
                         0.5 * spec.wheelbase_m) > spec.ground_clearance_m
    if not bumpers:
        return too_steep | crest
    overhang = 0.5 * (spec.length_m - spec.wheelbase_m)
    sag = bumper_sag(world.heights, world.grid.resolution, spec.wheelbase_m,
                     overhang) > spec.ground_clearance_m + BUMPER_RAISE_M
    return too_steep | crest | sag


def segment_hazard_m(mask: np.ndarray, origin_xy, resolution_m: float, start_xy,
                     goal_xy) -> float:
    """Metres of the straight segment start → goal (x, y [m]; a pose's yaw is ignored)
    on the True cells of ``mask`` (H, W), cell (r, c) covering [x0 + cΔ, x0 + (c+1)Δ) ×
    [y0 + rΔ, y0 + (r+1)Δ): the segment's length d times the share of its
    n = ⌈d / (Δ/2)⌉ + 1 evenly spaced samples (ends included, at least 2) on such cells;
    samples off the map count as no hazard."""
    grid = GridSpec(origin_xy, resolution_m, np.shape(mask))
    (sx, sy), (gx, gy) = start_xy[:2], goal_xy[:2]
    dist = float(np.hypot(gx - sx, gy - sy))
    n = max(2, int(np.ceil(dist / (0.5 * grid.resolution))) + 1)
    t = np.linspace(0.0, 1.0, n)
    r, c = grid.xy_to_cell(sx + t * (gx - sx), sy + t * (gy - sy))
    rows, cols = grid.shape
    on = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
    hit = np.zeros(n, bool)
    hit[on] = mask[r[on], c[on]]
    return dist * float(hit.mean())


@dataclass(frozen=True)
class HazardMap:
    """Cells some vehicle cannot cross, ``mask`` (H, W) bool on ``grid``; ``measure`` is
    the rule :meth:`length_m` applies (:func:`segment_hazard_m`; notebook 08's exercise
    plugs the learner's in)."""

    grid: GridSpec
    mask: np.ndarray
    measure: Callable[..., float] = field(default=segment_hazard_m, compare=False, repr=False)

    def length_m(self, start_xy, goal_xy) -> float:
        """Metres of the straight segment start → goal [m] that lie on hazard cells
        (sampled every half cell; points off the map count as no hazard)."""
        return self.measure(self.mask, self.grid.origin_xy, self.grid.resolution, start_xy,
                            goal_xy)

    @property
    def fraction(self) -> float:
        """Share of the map's cells that are hazards."""
        return float(self.mask.mean())


def hazard_map(world: World, vehicles: Iterable[str]) -> HazardMap:
    """The cells of ``world`` that at least one of ``vehicles`` cannot cross."""
    mask = np.zeros(world.grid.shape, bool)
    for v in vehicles:
        mask |= vehicle_hazards(world, v)
    return HazardMap(world.grid, mask)
