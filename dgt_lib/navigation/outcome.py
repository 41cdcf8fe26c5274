"""How a drive ends: the one outcome rule of trials and scripted drives
(paper: Experimental Protocol, Tables I and II).

The paper counts a navigation trial as a success when the vehicle reaches within 5 m
of the goal "without getting immobilized for greater than 10 seconds". The same rule
(:class:`OutcomeRule`) judges every closed loop online (:mod:`dgt_lib.navigation.drive`),
sample by sample, so every method is judged alike. The
immobility clock is :func:`dgt_lib.world.simulator.immobile_time` — the simulator's own.

Reasons (the vocabulary of :attr:`TrialOutcome.reason`):

==============  ==============================================================
``success``     within the goal tolerance (5 m) before any failure
``immobilized`` speed below ``IMMOBILE_SPEED_MPS`` for more than
                ``IMMOBILE_TIME_S`` continuously
``flipped``     the vehicle rolled over (the simulator's flag)
``timeout``     the time limit passed without success or failure
``no_path``     the planner found no path; the vehicle never drove
``diverged``    the vehicle left the map or the simulation diverged
``error``       the simulation or a component raised; ``detail`` says what
==============  ==============================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dgt_lib.world.simulator import IMMOBILE_SPEED_MPS  # noqa: F401 - beside the others

GOAL_TOLERANCE_M = 5.0  # paper, Tables I/II captions: "within 5 m of the goal"
IMMOBILE_TIME_S = 10.0  # paper: "immobilized for greater than 10 seconds"

REASONS: tuple[str, ...] = (
    "success", "immobilized", "flipped", "timeout", "no_path", "diverged", "error")


@dataclass(frozen=True)
class TrialOutcome:
    """How one closed-loop trial ended.

    ``success`` is True exactly when ``reason == "success"``; ``duration_s`` [s]
    is the time at which the outcome was decided (0 for ``no_path``);
    ``goal_distance_m`` [m] the distance to the goal then (NaN if unknown).
    """

    success: bool
    reason: str
    duration_s: float
    goal_distance_m: float = math.nan
    detail: str = ""

    def __post_init__(self):
        if self.reason not in REASONS:
            raise ValueError(f"unknown reason {self.reason!r}; valid: {', '.join(REASONS)}")
        if self.success != (self.reason == "success"):
            raise ValueError(f"success={self.success} contradicts reason {self.reason!r}")

    @classmethod
    def failure(
        cls, reason: str, duration_s: float = 0.0, goal_distance_m: float = math.nan, detail=""
    ) -> TrialOutcome:
        """A failed trial, e.g. ``TrialOutcome.failure("no_path")`` or
        ``TrialOutcome.failure("error", t, detail=repr(exc))``."""
        return cls(False, reason, float(duration_s), float(goal_distance_m), str(detail))


@dataclass(frozen=True)
class OutcomeRule:
    """When a drive ends and how: the first of, checked in this order,

    1. within ``goal_tolerance_m`` [m] of the goal (≤) → ``success``;
    2. the simulator's ``done_reason`` → ``flipped`` (or ``diverged`` for ``off_map`` /
       ``diverged``);
    3. immobile for more than ``immobilized_limit_s`` [s] → ``immobilized``;
    4. ``time_limit_s`` [s] reached → ``timeout``.

    Without a goal (``goal=None`` in :meth:`judge`) rule 1 never fires.
    """

    goal_tolerance_m: float = GOAL_TOLERANCE_M
    immobilized_limit_s: float = IMMOBILE_TIME_S
    time_limit_s: float = math.inf

    def judge(self, t: float, position, goal, immobile_s: float,
              done_reason: str | None = None) -> TrialOutcome | None:
        """The outcome at time ``t`` [s] at ``position`` (x, y[, z]) [m], or None to go on."""
        dist = math.nan if goal is None else float(
            math.hypot(position[0] - goal[0], position[1] - goal[1]))
        if goal is not None and dist <= self.goal_tolerance_m:
            return TrialOutcome(True, "success", t, dist)
        if done_reason is not None:
            reason = "flipped" if done_reason == "flipped" else "diverged"
            return TrialOutcome.failure(reason, t, dist, detail=done_reason)
        if immobile_s > self.immobilized_limit_s + 1e-9:  # (summed float steps)
            return TrialOutcome.failure("immobilized", t, dist)
        if t >= self.time_limit_s - 1e-9:
            return TrialOutcome.failure("timeout", t, dist)
        return None
