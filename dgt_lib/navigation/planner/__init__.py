"""Direction-aware Hybrid A* (paper: Traversability-Aware Path Planning).

The planner searches over continuous poses (x, y, θ) [m, m, rad] with three
forward arc primitives — straight, left and right at the vehicle's minimum
turning radius r_min — each of arc length s = ``step_m`` (paper: s = 1.6 m).
Two decoupled map layers drive it:

- the occupancy map ``(H, W)`` uint8 (0 free, 1 occupied, 2 unobserved, the
  last treated as occupied) rejects primitives that collide, checked at fine
  sub-steps along each arc with the vehicle's footprint;
- the directional costmap ``(K, H, W)`` in [0, 1] (layer k is heading
  θ_k = 2πk/K) prices each primitive at its successor cell, in the layer
  nearest to the travel direction, amplified by β (paper: β = 150).

Conventions (docs/ARCHITECTURE.md): rows grow with y, θ is counter-clockwise from +x. The
paper writes the travel direction as atan2(j' − j, i' − i) on grid indices; in
our grid the row index follows y and the column index follows x, so the same
direction in world terms is θ' = atan2(Δrow, Δcol) — travel toward +x reads
layer 0 and travel toward +y reads layer K/4.

Usage::

    planner = HybridAStar(costmap, occupancy, grid, min_turn_radius_m=5.7,
                          footprint=(6.4, 2.4), cfg=profile.planner)
    result = planner.plan((10.0, 20.0, 0.0), (120.0, 90.0))
    result.path            # (N, 3) x, y, θ at sub-step spacing
    result.cost            # Σ g_edge

:func:`plan` is the one-call form. A :class:`HybridAStar` keeps what depends
only on the map (footprint dilation, the 2D cost field) and the cost-to-go of
recent goals, so repeated queries on one map are cheaper.

Footprint approximation: the vehicle rectangle (length × width, centred on the
pose) is covered by an odd number n ≥ length/width of equal circles on its
long axis (:func:`footprint_circles`). A circle centre is snapped to its cell,
and the cell is blocked when an occupied or unobserved cell centre lies closer
than r_circle + ``safety_margin_m`` + res·√2/2. Hence at every checked sub-step
no occupied cell centre lies inside any footprint circle, hence none inside the
vehicle rectangle; the price is up to ~res·√2 of extra clearance.

Search: A* with f = g + w·h over the nodes' exact poses; a closed set over
(x, y, θ) cells of ``closed_cell_m`` × ``closed_cell_m`` × 360°/``theta_bins``
keeps the first node expanded in each cell (Hybrid A*'s state merging, the one
source of sub-optimality besides the weight w = ``heuristic_weight``). The
headings reachable from the start are θ_start + n·s/r_min, so the sub-step
offsets of the three arcs are tabulated once per turn count n and each
expansion checks all of them with one vectorised lookup. Heuristics:
``"euclidean"`` (the paper's: distance to the goal point) or ``"cost_to_go"``
(its max with a direction-aware 2D lower bound, :meth:`HybridAStar.cost_to_go`,
which also refutes unreachable goals before the search starts).

Deterministic: ties in the open list break by insertion order; no randomness.

Two backends run the same search (``HybridAStar(..., backend=...)``): ``"compiled"``,
the default, runs the search loop and the 2D cost-to-go's Dijkstra as machine code
compiled by numba (:mod:`.compiled`; compiled once, then cached on disk), and
``"python"`` is the plain-Python reference it was transcribed from. They expand the same
nodes in the same order and return the same plan to the bit
(``tests/test_planner_exact.py``); read ``_Search`` in :mod:`.search` to learn the
algorithm, :mod:`.compiled` only to see how it was made fast.

Modules: :mod:`.primitives` (arc primitives, the directional cost lookup and
the paper's cost model), :mod:`.collision` (footprint checks), :mod:`.heuristics`
(Euclidean and the 2D cost-to-go), :mod:`.shots` (Dubins / turn-then-straight
analytic shots), :mod:`.search` (:class:`HybridAStar` and one query's search),
:mod:`.compiled` (the same search, compiled), :mod:`.result` (search nodes,
:class:`PlanResult`), :mod:`.validation`.
"""

from dgt_lib.core.vehicles import footprint_circles
from dgt_lib.navigation.planner.heuristics import HEURISTICS, CostToGo, step_cell_bounds
from dgt_lib.navigation.planner.primitives import (
    amplified_cost,
    arc_poses,
    edge_cost,
    travel_heading_bin,
)
from dgt_lib.navigation.planner.result import InvalidQueryError, PlanResult
from dgt_lib.navigation.planner.search import BACKENDS, HybridAStar, plan
from dgt_lib.navigation.planner.shots import dubins_path, sample_segments, turn_then_straight
from dgt_lib.navigation.planner.validation import check_query_on_world

__all__ = [
    "BACKENDS",
    "HEURISTICS",
    "CostToGo",
    "HybridAStar",
    "InvalidQueryError",
    "PlanResult",
    "amplified_cost",
    "arc_poses",
    "check_query_on_world",
    "dubins_path",
    "edge_cost",
    "footprint_circles",
    "plan",
    "sample_segments",
    "step_cell_bounds",
    "travel_heading_bin",
    "turn_then_straight",
]
