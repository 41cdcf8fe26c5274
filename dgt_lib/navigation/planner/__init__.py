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

Rows grow with y, θ is counter-clockwise from +x, so the paper's travel direction
atan2(j' − j, i' − i) reads θ' = atan2(Δrow, Δcol) here.

Usage::

    planner = HybridAStar(costmap, occupancy, grid, min_turn_radius_m=5.7,
                          footprint=(6.4, 2.4), cfg=profile.planner)
    result = planner.plan((10.0, 20.0, 0.0), (120.0, 90.0))
    result.path            # (N, 3) x, y, θ at sub-step spacing
    result.cost            # Σ g_edge

    search = planner.search(start, goal)   # the reference search, step by step
    search.push_start()
    for step in search.steps():            # pop, expand the primitives, push
        ...

:meth:`HybridAStar.for_vehicle` takes a vehicle's turning radius and footprint. A
:class:`HybridAStar` keeps what depends only on the map (:class:`PlannerMaps`: footprint
dilation, the 2D cost field) and the cost-to-go of recent goals, so repeated queries on one
map are cheaper.

Search: A* with f = g + w·h over the nodes' exact poses and a closed set over (x, y, θ)
cells (Hybrid A*'s state merging); heuristics ``"euclidean"`` (the paper's) or
``"cost_to_go"`` (its max with a direction-aware 2D lower bound, which also refutes
unreachable goals). Deterministic: ties break by insertion order. A failed query says which
failure it is (``PlanResult.failure``): ``"no_path"`` (proven: the open list emptied, or the
2D bound refutes the goal) or ``"budget"`` (``max_expansions`` or ``max_time_s`` ran out
first, so a path may still exist).

Two backends run the same search (``HybridAStar(..., backend=...)``): ``"compiled"``, the
default, compiled by numba (:mod:`.compiled`; compiled once, then cached on disk), and
``"python"``, the reference :class:`Search` (:mod:`.search`) it was transcribed from. They
expand the same nodes in the same order and return the same plan to the bit
(``tests/test_planner_exact.py``). Read :mod:`.search` to learn the algorithm.

The modules, the footprint check, the conventions and the heuristic's proof:
docs/planner.md.
"""

import contextlib
import hashlib
from pathlib import Path


def drop_stale_numba_cache(package: Path, modules: str = "compiled*") -> None:
    """Delete numba's cached machine code of ``package``'s ``modules`` once any of their
    sources changed. numba checks a cached function against its own file only, and
    ``compiled.search`` carries the helpers of the other ``compiled_*.py`` compiled into
    it: after an edit to a helper alone, the search would go on running the old helper.
    A digest of the sources is kept beside the cache (``__pycache__``)."""
    sources = b"".join(p.read_bytes() for p in sorted(package.glob(f"{modules}.py")))
    digest = hashlib.sha256(sources).hexdigest()
    stamp = package / "__pycache__" / f"{modules.strip('*')}.sources.sha256"
    with contextlib.suppress(OSError):  # a read-only install: numba cannot cache there either
        if not stamp.exists() or stamp.read_text() != digest:
            stamp.parent.mkdir(exist_ok=True)
            for cached in stamp.parent.glob(f"{modules}.nb[ic]"):
                cached.unlink(missing_ok=True)  # another process may have been first
            stamp.write_text(digest)


drop_stale_numba_cache(Path(__file__).parent)

# ruff: noqa: E402, F401 - the names below are this package's interface, re-exported
from dgt_lib.navigation.planner.heuristics import HEURISTICS, CostToGo, step_cell_bounds
from dgt_lib.navigation.planner.hybrid_astar import BACKENDS, HybridAStar
from dgt_lib.navigation.planner.maps import PlannerMaps
from dgt_lib.navigation.planner.primitives import (
    amplified_cost,
    arc_poses,
    edge_cost,
    step_cost,
    travel_heading_bin,
)
from dgt_lib.navigation.planner.result import (
    BUDGET,
    FAILURES,
    NO_PATH,
    InvalidQueryError,
    PlanResult,
)
from dgt_lib.navigation.planner.search import Expansion, Priced, Search
from dgt_lib.navigation.planner.shots import dubins_path, sample_segments, turn_then_straight
from dgt_lib.navigation.planner.validation import check_query_on_world
