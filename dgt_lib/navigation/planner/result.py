"""Search nodes and the outcome of a query (:class:`PlanResult`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from dgt_lib.core.geometry import wrap_angle
from dgt_lib.navigation.planner.primitives import PrimitiveSet

SHOT = 3  # Node.primitive of a node reached by an analytic shot (0-2: the arc primitives)

NO_PATH, BUDGET = "no_path", "budget"
"""The kinds of failure (:attr:`PlanResult.failure`): no path exists (every pose the search
can reach was expanded, or the 2D relaxation refutes the goal), or the search budget
(``max_expansions`` or ``max_time_s``) ran out with nodes still open."""

FAILURES: tuple[str, ...] = ("", NO_PATH, BUDGET)
"""The values of :attr:`PlanResult.failure` ("": the goal was reached)."""


class InvalidQueryError(ValueError):
    """A start or goal that cannot be planned for (off the map, in an obstacle)."""


class Node(NamedTuple):
    """One node of the search tree.

    x, y: position [m]; turns: n, the heading being θ_start + n·Δθ; row, col: its
    cell; g: cost-so-far; parent: the node it was reached from (None at the
    start); primitive: index of the arc primitive that reached it, :data:`SHOT`
    for an analytic shot, −1 at the start; is_goal: whether it lies in the goal
    region; key: its closed-set cell (−1 for a shot); shot: the shot's poses.
    """

    x: float
    y: float
    turns: int
    row: int
    col: int
    g: float
    parent: Node | None
    primitive: int
    is_goal: bool
    key: int
    shot: np.ndarray | None = None


@dataclass(frozen=True)
class PlanResult:
    """The outcome of one query.

    path: (N, 3) poses x [m], y [m], θ [rad, in [0, 2π)] from start to goal at
        sub-step spacing (≤ ``substep_m``); shape (0, 3) when ``success`` is False.
    cost: Σ g_edge of the path (∞ on failure).
    expansions: nodes taken from the open list and expanded.
    time_s: wall time of the query, including the heuristic's set-up.
    success: whether the goal was reached.
    reason: "reached goal" or why not, in words: starts with "no path exists" or
        "search budget exhausted" (then it names the setting to raise).
    nodes: (M, 3) the search nodes on the path (primitive end poses; the goal
        pose when an analytic shot finished it).
    node_costs: (M,) cost-so-far g at each node (node_costs[-1] == cost).
    expanded_xy: (E, 2) positions of all expanded nodes, in expansion order.
    failure: which failure, one of :data:`FAILURES`: "" on success, :data:`NO_PATH` when
        no path exists (proven: the search's reachable set is exhausted, or the 2D
        relaxation refutes the goal), :data:`BUDGET` when ``max_expansions`` or
        ``max_time_s`` stopped the search with nodes still open (a path may exist).
    """

    path: np.ndarray
    cost: float
    expansions: int
    time_s: float
    success: bool
    reason: str
    nodes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    node_costs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    expanded_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    failure: str = ""

    def __post_init__(self):
        if self.failure not in FAILURES or (self.failure == "") != self.success:
            raise ValueError(f"a PlanResult with success={self.success} has failure "
                             f"{self.failure!r}; valid: {FAILURES} ('' exactly on success)")

    @property
    def length_m(self) -> float:
        """Length of the path polyline [m] (0 on failure)."""
        if len(self.path) < 2:
            return 0.0
        return float(np.hypot(*np.diff(self.path[:, :2], axis=0).T).sum())


def _expanded_array(expanded) -> np.ndarray:
    return np.asarray(expanded, dtype=np.float64).reshape(-1, 2)


def _failed(kind: str, reason: str, expanded: list | np.ndarray, t0: float) -> PlanResult:
    """The result of a query that found no path: ``kind`` one of :data:`NO_PATH`,
    :data:`BUDGET`; ``expanded`` the expanded (x, y); ``t0`` the query's
    ``time.perf_counter()`` at its start."""
    return PlanResult(  # whose __post_init__ rejects any other kind
        path=np.zeros((0, 3)), cost=np.inf, expansions=len(expanded),
        time_s=time.perf_counter() - t0, success=False, reason=reason,
        expanded_xy=_expanded_array(expanded), failure=kind,
    )


UNREACHABLE_2D = "the goal is unreachable even in the 2D relaxation"
"""Why no path exists when the cost-to-go refutes the goal before the search starts."""

OPEN_LIST_EMPTY = "every pose the search can reach was expanded (open list exhausted)"
"""Why no path exists when the search ran out of nodes to expand."""


def no_path(why: str, expanded: list | np.ndarray, t0: float) -> PlanResult:
    """The result of a query that has no path: ``why`` (:data:`UNREACHABLE_2D` or
    :data:`OPEN_LIST_EMPTY`) says how that was proven."""
    return _failed(NO_PATH, f"no path exists: {why}", expanded, t0)


def budget_exhausted(setting: str, limit: float, expanded: list | np.ndarray,
                     t0: float) -> PlanResult:
    """The result of a search that ``setting`` (``"max_expansions"`` or ``"max_time_s"``,
    of value ``limit``: expansions or seconds) stopped with nodes still open: its reason
    names the setting and how to raise it (``--set planner.<setting>=<2 × limit>``)."""
    if setting == "max_expansions":
        spent = f"{len(expanded)} expansions"
        shown, raised = str(int(limit)), str(2 * int(limit))
    elif setting == "max_time_s":
        spent = f"{len(expanded)} expansions in {time.perf_counter() - t0:.1f} s"
        shown, raised = f"{limit:g}", f"{2 * limit:g}"
    else:
        raise ValueError(f"a search budget is max_expansions or max_time_s, got {setting!r}")
    return _failed(BUDGET, f"search budget exhausted after {spent} (planner.{setting}="
                           f"{shown}): no path found yet, none ruled out; raise it, e.g. "
                           f"--set planner.{setting}={raised}", expanded, t0)


def success(goal: Node, primitives: PrimitiveSet, expanded: list, t0: float) -> PlanResult:
    """The result of a query that reached ``goal``: the path traced back to the start."""
    chain = []
    node = goal
    while node is not None:
        chain.append(node)
        node = node.parent
    chain.reverse()
    first = (chain[0].x, chain[0].y, primitives.start_heading)
    pieces = [np.array([first])]
    nodes = [first]
    for node in chain[1:]:
        if node.primitive == SHOT:
            piece = node.shot
        else:
            p = node.parent
            piece = primitives.poses(p.x, p.y, p.turns, node.primitive)
        pieces.append(piece)
        nodes.append(tuple(piece[-1]))
    path = np.concatenate(pieces)
    path[:, 2] = wrap_angle(path[:, 2])
    nodes = np.asarray(nodes, dtype=np.float64)
    nodes[:, 2] = wrap_angle(nodes[:, 2])
    return PlanResult(
        path=path,
        cost=float(goal.g),
        expansions=len(expanded),
        time_s=time.perf_counter() - t0,
        success=True,
        reason="reached goal",
        nodes=nodes,
        node_costs=np.asarray([node.g for node in chain], dtype=np.float64),
        expanded_xy=_expanded_array(expanded),
    )
