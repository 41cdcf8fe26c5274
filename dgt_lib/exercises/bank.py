"""The notebooks' exercises: for each, the library reference it is graded against, the
inputs it is tried on (each exposing one common mistake, with its hint) and the notebook
that asks it. Graded by :mod:`dgt_lib.exercises`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dgt_lib.perception.bev import BEV_RESOLUTION_M


@dataclass(frozen=True)
class Case:
    """One test input: positional ``args`` for both functions, and the hint shown when the
    learner's answer disagrees with the reference on it."""

    args: tuple
    hint: str


@dataclass(frozen=True)
class Exercise:
    """An exercise: the notebook it belongs to, the library reference (called with each
    case's args), the cases (built on demand: some need torch), and the tolerance of the
    comparison. ``normalize`` maps both answers to a canonical form before comparing
    (e.g. an unordered set of pairs)."""

    notebook: str
    reference: Callable[..., Any]
    cases: Callable[[], Sequence[Case]]
    atol: float = 1e-6
    normalize: Callable[[Any], Any] | None = None


# ----------------------------------------------------------------------------- references
# Thin adapters that call the library's functions with the exercise's signature.

def _cell_plane(points: np.ndarray) -> tuple[float, float, float]:
    """(h, a, b) of the plane z = h + a·x + b·y through the points of one 0.4 m cell, by
    the BEV's own per-cell fit (:func:`dgt_lib.perception.cell_planes.fit_cell_planes`, via
    a one-cell :class:`~dgt_lib.perception.bev.BEVAccumulator`); points (N, 3) [m], x, y
    offsets from the cell centre."""
    from dgt_lib.core.geometry import GridSpec
    from dgt_lib.perception.bev import BEVAccumulator

    half = BEV_RESOLUTION_M / 2.0
    acc = BEVAccumulator(GridSpec((-half, -half), BEV_RESOLUTION_M, (1, 1)))
    points = np.asarray(points, dtype=np.float64)
    acc.add_points(points, np.zeros_like(points))
    planes = acc.planes()
    return (float(planes.height[0, 0]), float(planes.slope_x[0, 0]),
            float(planes.slope_y[0, 0]))


def _locomotion(displacement_m, dt_s):
    from dgt_lib.perception.locomotion import locomotion

    return locomotion(displacement_m, dt_s)


def _masked_loss(pred, labels, head):
    from dgt_lib.learning.training import masked_loss

    return masked_loss(pred, labels, head)


def _heading_bin(theta, n_headings):
    from dgt_lib.core.geometry import nearest_heading_bin

    return nearest_heading_bin(theta, n_headings)


def _edge_cost(length_m: float, cost: float, beta: float) -> float:
    from dgt_lib.navigation.planner.primitives import amplified_cost, edge_cost

    return edge_cost(length_m, amplified_cost(cost, beta))


def _slope_locomotion(theta, theta0, theta_min, theta_max, p_u, p_d):
    from dgt_lib.mapping.baselines import SlopeModel

    return SlopeModel(theta0, theta_min, theta_max, p_u, p_d).locomotion(theta)


def _hazard_length(mask, origin_xy, resolution_m, start, goal) -> float:
    from dgt_lib.evaluation.hazards import segment_hazard_m

    return segment_hazard_m(mask, origin_xy, resolution_m, start, goal)


def _changed_mask(old_channels, old_observed, new_channels, new_observed) -> np.ndarray:
    """The cells an incremental costmap update starts from
    (:func:`dgt_lib.perception.bev.changed_mask` on two BEV maps of one grid); all
    False when nothing changed (where the library returns None)."""
    from dgt_lib.core.geometry import GridSpec
    from dgt_lib.perception.bev import BEVMap, changed_mask

    grid = GridSpec((0.0, 0.0), BEV_RESOLUTION_M, np.shape(new_observed))
    counts = np.zeros(grid.shape, np.int64)
    old = (None if old_channels is None
           else BEVMap(grid, np.asarray(old_channels), np.asarray(old_observed), counts))
    mask = changed_mask(old, BEVMap(grid, np.asarray(new_channels), np.asarray(new_observed),
                                    counts))
    return np.zeros(grid.shape, bool) if mask is None else mask


def _contrast_pairs(true_cost, valid, threshold):
    from dgt_lib.evaluation.accuracy import contrast_pairs

    return contrast_pairs(true_cost, valid, threshold)


def _pair_set(answer) -> np.ndarray:
    """(cells, k) → the (P, 2) pairs sorted: the order the learner lists them in is free."""
    cells, k = (np.asarray(a, dtype=np.int64).ravel() for a in answer)
    if cells.shape != k.shape:
        raise ValueError("cells and k must have the same length")
    return np.array(sorted(zip(cells.tolist(), k.tolist(), strict=True)),
                    dtype=np.int64).reshape(-1, 2)


# ----------------------------------------------------------------------------- cases
def _plane_points(h: float, a: float, b: float, centre_xy=(0.0, 0.0), n: int = 30,
                  seed: int = 0) -> np.ndarray:
    """(n, 3) points on z = h + a·x + b·y, x, y spread over ±0.12 m around centre_xy
    (offsets from the cell centre [m], inside a BEV cell of ±0.2 m)."""
    xy = np.random.default_rng(seed).uniform(-0.12, 0.12, (n, 2)) + np.asarray(centre_xy)
    return np.column_stack([xy, h + xy @ np.array([a, b])])


def _plane_cases() -> list[Case]:
    return [
        Case((_plane_points(2.0, 0.0, 0.0),),
             "a level cell: slopes a = b = 0 and h = the points' height"),
        Case((_plane_points(1.0, 0.3, 0.0, seed=1),),
             "a tilts along x (east): fit z = h + a·x + b·y by least squares "
             "(np.linalg.lstsq on the columns [1, x, y])"),
        Case((_plane_points(1.0, 0.0, -0.2, seed=2),),
             "b is the slope along y (north); return (h, a, b) in that order"),
        Case((_plane_points(0.5, 0.25, 0.1, centre_xy=(0.06, -0.05), seed=3),),
             "h is the plane's height at the cell centre (x = y = 0), not the mean z of "
             "points that sit off-centre"),
    ]


def _locomotion_cases() -> list[Case]:
    return [
        Case((5.0, 1.0), "at full speed, ‖Δx‖ = u·Δt with u = 5 m/s, L = 1"),
        Case((0.0, 1.0), "standing still gives exp(−1/(2σ²)) with σ = 1/3, i.e. exp(−4.5)"),
        Case((2.5, 1.0), "the error is relative: (u·Δt − ‖Δx‖)/(u·Δt), squared, "
                         "times −1/(2σ²)"),
        Case((10.0, 2.0), "the expected distance is u·Δt: divide by it, not by u"),
        Case((7.5, 1.0), "driving faster than u is as bad as driving as much slower "
                         "(the relative error is squared)"),
        Case((np.array([0.0, 2.5, 5.0]), np.array([1.0, 1.0, 1.0])),
             "work elementwise on arrays (np.exp, no math.exp or Python loops over floats)"),
    ]


def _masked_loss_cases() -> list[Case]:
    import torch

    g = torch.Generator().manual_seed(0)
    pred1 = torch.tensor([[0.9, 0.2, 0.4, 0.7]])
    pred = torch.rand(6, 4, generator=g)
    labels = torch.rand(6, generator=g)
    return [
        Case((pred1, torch.tensor([0.5]), torch.tensor([2])),
             "only the head of the vehicle that collected the patch counts: "
             "L̂ = pred[i, head[i]] (e.g. pred.gather(1, head[:, None]))"),
        Case((pred, labels, torch.tensor([0, 3, 1, 1, 2, 0])),
             "average the squared errors over the batch (a mean, not a sum)"),
        Case((pred, pred[torch.arange(6), torch.tensor([3, 2, 1, 0, 3, 2])],
              torch.tensor([3, 2, 1, 0, 3, 2])),
             "labels equal to the own heads' predictions give a loss of exactly 0"),
    ]


def _heading_cases() -> list[Case]:
    deg = np.radians
    return [
        Case((deg(10.0), 8), "θ_k = 2πk/K: k = 0 faces east (+x), bins 45° apart for K = 8"),
        Case((deg(40.0), 8), "round to the nearest bin: 40° is nearest 45° (k = 1), "
                             "do not floor"),
        Case((deg(90.0), 8), "bins turn counter-clockwise: north (90°) is k = 2"),
        Case((deg(-20.0), 8), "wrap θ into [0, 2π) first: −20° is nearest θ_0"),
        Case((deg(-100.0), 8), "a negative heading: −100° = 260°, nearest 270° (k = 6)"),
        Case((deg(350.0), 8), "after the last bin comes bin 0 again: take k modulo K"),
        Case((deg(30.0), 16), "use K, not a fixed 8: for K = 16 the bins are 22.5° apart"),
        Case((deg(np.array([0.0, 100.0, 200.0, 300.0])), 8),
             "work elementwise on arrays and return integers"),
    ]


def _edge_cost_cases() -> list[Case]:
    return [
        Case((1.0, 0.0, 150.0), "with cost C = 0 a move costs its length s [m]"),
        Case((1.0, 0.5, 0.0), "with β = 0, C' = C and g = s·(1 + C)"),
        Case((1.0, 0.5, 150.0), "C' = C·(1 + β·C): β multiplies C², the penalty is "
                                "super-linear"),
        Case((0.8, 0.3, 150.0), "g_edge = s·(1 + C'): the length multiplies the whole "
                                "(1 + C')"),
    ]


def _slope_cases() -> list[Case]:
    deg = np.radians
    m = (deg(2.0), deg(-20.0), deg(15.0), 2.0, 0.5)  # θ0, θmin, θmax, p_u, p_d
    return [
        Case((deg(2.0), *m), "at θ = θ0 the terrain is fully traversable: L_sb = 1"),
        Case((deg(8.5), *m), "uphill (θ ≥ θ0): 1 − ((θ − θ0)/(θmax − θ0))^p_u"),
        Case((deg(-9.0), *m), "downhill (θ < θ0): 1 − ((θ0 − θ)/(θ0 − θmin))^p_d, "
                              "with its own exponent p_d"),
        Case((deg(20.0), *m), "beyond θmax (or below θmin) L_sb = 0"),
        Case((deg(np.array([-25.0, -20.0, 0.0, 15.0, 30.0])), *m),
             "work elementwise on arrays; L_sb(θmin) = L_sb(θmax) = 0"),
    ]


def _hazard_cases() -> list[Case]:
    cross = np.zeros((10, 10), bool)
    cross[:, 4:6] = cross[4:6, :] = True  # x or y ∈ [4, 6) on a 1 m grid: symmetric
    band = np.zeros((6, 10), bool)
    band[1, :5] = True  # y ∈ [1, 2), x < 5 only: not symmetric in x and y
    edge = np.zeros((6, 10), bool)
    edge[2, 9] = True  # the last column: where a negative column index wraps to
    return [
        Case((cross, (0.0, 0.0), 1.0, (0.5, 2.5), (9.5, 2.5)),
             "metres = d × the share of the n = ⌈d/(Δ/2)⌉ + 1 evenly spaced samples (both "
             "ends included) that fall on hazard cells, d the segment's length"),
        Case((band, (0.0, 0.0), 1.0, (3.5, 0.5, 1.2), (3.5, 5.5)),
             "mask[row, col]: rows run along y, columns along x; and start is the query's "
             "pose (x, y, yaw): use its x, y only"),
        Case((cross, (-2.0, 10.0), 1.0, (-1.5, 12.5, 0.0), (7.5, 11.0)),
             "cell (r, c) covers x ∈ [x0 + cΔ, x0 + (c+1)Δ): subtract the grid origin (the "
             "corner of cell (0, 0)) before dividing by Δ, then floor"),
        Case((band, (0.0, 0.0), 0.4, (0.2, 0.1, 0.0), (1.0, 2.3)),
             "use the grid's Δ: cells Δ wide and samples every Δ/2 at most"),
        Case((edge, (0.0, 0.0), 1.0, (3.5, 2.5, 3.1), (-3.5, 2.5)),
             "samples off the map count as no hazard (a negative index would wrap round to "
             "the far edge of the map)"),
    ]


def _changed_cases() -> list[Case]:
    rng = np.random.default_rng(0)
    old = rng.uniform(0.1, 1.0, (6, 4, 5)).astype(np.float32)
    seen = np.ones((4, 5), bool)
    seen[0, :] = False
    old[:, ~seen] = 0.0
    new_cell, new_seen = old.copy(), seen.copy()
    new_cell[:, 0, 2], new_seen[0, 2] = (0.3, 0.5, 0.2, 1.4, 0.01, 0.1), True
    moved = old.copy()
    moved[3, 2, 1] += np.float32(1e-3)  # H̄ of a re-observed cell moves by 1 mm
    grad = old.copy()
    grad[5, 3, 4] += np.float32(0.05)  # only ‖∇H̄‖ changes: a neighbour's height moved
    dark = seen.copy()
    dark[0, 0] = True  # seen for the first time, every channel 0 (black, level, at 0 m)
    return [
        Case((old, seen, new_cell, new_seen),
             "a cell seen for the first time has changed: its observed flag flips"),
        Case((old, seen, moved, seen),
             "a re-observed cell whose H̄ moved, even by a millimetre, has changed: compare "
             "the values exactly (no tolerance), not only the observed flags"),
        Case((old, seen, grad, seen),
             "compare all six channels (R, G, B, H̄, σ_H, ‖∇H̄‖), not only the height"),
        Case((old, seen, old, dark),
             "compare the observed flags too: a new cell's channels may all be 0"),
        Case((None, None, old, seen),
             "the first frame (old is None): every observed cell of the new map has "
             "changed, the unobserved ones have not"),
        Case((old, seen, old.copy(), seen.copy()),
             "nothing changed: return an all-False (H, W) mask"),
    ]


def _contrast_cases() -> list[Case]:
    t = np.array([[0.1, 0.2, 0.3, 0.4, 0.9, 0.2, 0.3, 0.4],
                  [0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5],
                  [0.9, 0.0, 0.3, 0.8, 0.1, 0.6, 0.3, 0.0]])
    valid = np.ones_like(t, dtype=bool)
    some = valid.copy()
    some[2, 7] = False
    return [
        Case((t, valid, 0.3), "θ_k's opposite heading is θ_{k+K/2}; list each pair once, "
                              "with k < K/2, as (cell indices, k)"),
        Case((t, some, 0.3), "both samples of a pair must be valid"),
        Case((t, valid, 0.0), "a pair counts when |C*(θ_k) − C*(θ_{k+K/2})| is strictly "
                              "more than the threshold"),
    ]


OUTCOME_REASONS = ("driving", "success", "flipped", "diverged", "immobilized", "timeout")
"""What :func:`_trial_outcome` answers: ``driving`` while the rule has not decided."""


def _trial_outcome(goal_distance_m, immobile_s, done_reason, t_s, time_limit_s) -> str:
    """The paper's outcome rule by :class:`~dgt_lib.navigation.outcome.OutcomeRule`, on a
    state at ``goal_distance_m`` [m] from the goal, immobile for ``immobile_s`` [s], with
    the simulator's ``done_reason`` (None, ``"flipped"``, ``"off_map"``, ``"diverged"``)
    at ``t_s`` [s]: the reason, or ``"driving"``."""
    from dgt_lib.navigation.outcome import OutcomeRule

    outcome = OutcomeRule(time_limit_s=time_limit_s).judge(
        t_s, (goal_distance_m, 0.0), (0.0, 0.0), immobile_s, done_reason)
    return "driving" if outcome is None else outcome.reason


def _reason_index(reason) -> int:
    """A reason as its index in :data:`OUTCOME_REASONS` (numbers are what the grader
    compares); anything else is refused."""
    return OUTCOME_REASONS.index(reason)


def _outcome_cases() -> list[Case]:
    return [
        Case((3.0, 0.0, None, 20.0, 60.0), "within 5 m of the goal the trial is a success"),
        Case((5.0, 0.0, None, 20.0, 60.0), "the goal tolerance includes 5 m itself (≤ 5 m)"),
        Case((20.0, 0.0, None, 20.0, 60.0), "far from the goal, moving, in time: "
                                             "return \"driving\""),
        Case((20.0, 10.5, None, 30.0, 60.0), "below 0.25 m/s for more than 10 s: "
                                              "\"immobilized\""),
        Case((20.0, 10.0, None, 30.0, 60.0), "immobilised for *more than* 10 s: exactly 10 s "
                                              "is still driving"),
        Case((20.0, 12.0, "flipped", 30.0, 60.0), "the simulator's flip ends the trial before "
                                                   "the immobility clock is read"),
        Case((4.0, 12.0, "flipped", 30.0, 60.0), "the goal is checked first: within 5 m is a "
                                                  "success even on the step it flips"),
        Case((20.0, 0.0, "off_map", 30.0, 60.0), "leaving the map (or a diverged simulation) "
                                                  "is \"diverged\", not \"flipped\""),
        Case((20.0, 3.0, None, 60.0, 60.0), "at the time limit an undecided trial is a "
                                             "\"timeout\""),
    ]


def _mppi_weights(cost, temperature):
    from dgt_lib.navigation.control.mppi import mppi_weights

    return mppi_weights(np.asarray(cost, np.float64), temperature)


def _weight_cases() -> list[Case]:
    return [
        Case((np.array([1.0, 2.0, 3.0]), 1.0), "w_b = exp(−(S_b − min S)/λ), normalised: "
                                               "the cheapest sample weighs most"),
        Case((np.array([0.5, 0.6, 0.9, 0.5]), 0.3), "divide by λ inside the exponential"),
        Case((np.array([2.0, 2.0]), 0.3), "η = Σ_b exp(…): the weights sum to 1"),
        Case((np.array([1000.0, 1000.2, 1003.0]), 0.05),
             "subtract min S before the exponential: exp(−1000/λ) is 0 in floating point "
             "and 0/0 is nan"),
        Case((np.array([0.3, 0.1, 0.2, 0.7, 0.1]), 3.0), "a large λ spreads the weight over "
                                                         "many samples"),
    ]


def _mean_command(cmd_t, cmd_v, a, b):
    from dgt_lib.perception.locomotion import mean_command

    return mean_command(*(np.asarray(x, np.float64) for x in (cmd_t, cmd_v, a, b)))


def _command_cases() -> list[Case]:
    t3 = np.array([0.0, 1.0, 2.0])
    return [
        Case((t3, np.full(3, 2.0), np.array([0.2]), np.array([1.2])),
             "a command that never changes is its own mean"),
        Case((t3, np.array([4.0, 0.0, 4.0]), np.array([0.5]), np.array([1.5])),
             "each command holds until the next: weight it by how long it holds"),
        Case((np.array([0.0, 0.2, 1.0]), np.array([5.0, 1.0, 5.0]), np.array([0.1]),
              np.array([1.1])), "weight by time, not by message: 0.1 s at 5, 0.8 s at 1, "
                                "0.1 s at 5 m/s"),
        Case((np.array([0.0, 1.0]), np.array([2.0, 3.0]), np.array([1.5]), np.array([2.5])),
             "after the last command, it still holds"),
        Case((t3, np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.5, 1.2]),
              np.array([1.0, 1.5, 2.2])), "one mean per window: a and b are arrays"),
    ]


EXERCISES: dict[str, Exercise] = {
    # the BEV's fit pulls slopes weakly towards its neighbourhood's: plain least squares
    # lands within 5e-4 of it on these points
    "cell_plane": Exercise("01_terrain_and_bev", _cell_plane, _plane_cases, atol=2e-3),
    "locomotion": Exercise("02_locomotion_labels", _locomotion, _locomotion_cases),
    "masked_loss": Exercise("03_multitask_training", _masked_loss, _masked_loss_cases),
    "heading_bin": Exercise("04_directional_inference", _heading_bin, _heading_cases),
    "edge_cost": Exercise("05_hybrid_astar", _edge_cost, _edge_cost_cases),
    "slope_locomotion": Exercise("07_experiment2_ridge", _slope_locomotion, _slope_cases,
                                 atol=1e-5),
    "hazard_length": Exercise("08_experiment3_multitask", _hazard_length, _hazard_cases),
    "changed_mask": Exercise("10_incremental_mapping", _changed_mask, _changed_cases),
    "contrast_pairs": Exercise("09_costmap_accuracy", _contrast_pairs, _contrast_cases,
                               normalize=_pair_set),
    "trial_outcome": Exercise("06_experiment1_hill", _trial_outcome, _outcome_cases,
                              normalize=_reason_index),
    "mppi_weights": Exercise("11_mppi_control", _mppi_weights, _weight_cases),
    "mean_command": Exercise("12_your_robot", _mean_command, _command_cases),
}
"""Every exercise by name; ``notebook`` says where it is asked."""
