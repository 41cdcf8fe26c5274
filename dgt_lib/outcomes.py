"""Trial outcomes and success-rate statistics (paper: Tables I and II).

The paper counts a navigation trial as a success when the vehicle reaches
within 5 m of the goal "without getting immobilized for greater than 10
seconds". This module turns recorded traces into a :class:`TrialOutcome`
(pure functions, so the same rule judges every method), offers an online
:class:`ImmobilityMonitor` for the closed loop, and reports success rates k/n
with Wilson score intervals beside the paper's own numbers.

Reasons (the vocabulary of :attr:`TrialOutcome.reason`):

==============  ==============================================================
``success``     within ``GOAL_TOLERANCE_M`` of the goal before any failure
``immobilized`` speed below ``IMMOBILE_SPEED_MPS`` for more than
                ``IMMOBILE_TIME_S`` continuously
``flipped``     the vehicle rolled over (the simulator's flag)
``timeout``     the time limit passed without success or failure
``no_path``     the planner found no path; the vehicle never drove
``diverged``    the closed loop left the map or the path (the caller's flag)
``error``       the simulation or a component raised; ``detail`` says what
==============  ==============================================================
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

GOAL_TOLERANCE_M = 5.0  # paper, Tables I/II captions: "within 5 m of the goal"
IMMOBILE_TIME_S = 10.0  # paper: "immobilized for greater than 10 seconds"
IMMOBILE_SPEED_MPS = 0.25  # ours (as dgt_lib.sim): the paper gives no speed threshold

REASONS: tuple[str, ...] = (
    "success",
    "immobilized",
    "flipped",
    "timeout",
    "no_path",
    "diverged",
    "error",
)


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


class ImmobilityMonitor:
    """Online immobility check for a control loop: call :meth:`update` every step.

    Immobilized = speed below ``speed_threshold_mps`` continuously for more than
    ``duration_s`` [s] (paper: "immobilized for greater than 10 seconds").
    """

    def __init__(
        self, speed_threshold_mps: float = IMMOBILE_SPEED_MPS, duration_s: float = IMMOBILE_TIME_S
    ):
        if speed_threshold_mps <= 0 or duration_s <= 0:
            raise ValueError("speed_threshold_mps and duration_s must be > 0")
        self.speed_threshold_mps = float(speed_threshold_mps)
        self.duration_s = float(duration_s)
        self.reset()

    def reset(self) -> None:
        """Forget the history (e.g. at the start of a trial)."""
        self._slow_since: float | None = None
        self._last_t: float | None = None

    def update(self, t: float, speed: float) -> bool:
        """Record speed [m/s] (its magnitude counts) at time ``t`` [s]; True once the
        vehicle has been immobile for more than ``duration_s``."""
        if self._last_t is not None and t < self._last_t:
            raise ValueError(f"time went backwards: {t} after {self._last_t}")
        self._last_t = t
        if abs(speed) >= self.speed_threshold_mps:
            self._slow_since = None
            return False
        if self._slow_since is None:
            self._slow_since = t
        return self.immobile_for_s > self.duration_s

    @property
    def immobile_for_s(self) -> float:
        """How long [s] the vehicle has been below the threshold so far (0 if moving)."""
        if self._slow_since is None or self._last_t is None:
            return 0.0
        return self._last_t - self._slow_since


def first_goal_reach(positions, goal, tolerance_m: float = GOAL_TOLERANCE_M) -> int | None:
    """Index of the first sample within ``tolerance_m`` [m] of ``goal`` (planar
    distance; positions ``(T, 2 or 3)``, goal ``(2,)`` or more), or None."""
    p = np.asarray(positions, dtype=np.float64)
    g = np.asarray(goal, dtype=np.float64)[:2]
    if p.ndim != 2 or p.shape[1] < 2:
        raise ValueError(f"positions must be (T, 2) or (T, 3), got {p.shape}")
    hits = np.flatnonzero(np.hypot(p[:, 0] - g[0], p[:, 1] - g[1]) <= tolerance_m)
    return int(hits[0]) if hits.size else None


def first_immobilized(
    times,
    speeds,
    speed_threshold_mps: float = IMMOBILE_SPEED_MPS,
    duration_s: float = IMMOBILE_TIME_S,
) -> int | None:
    """Index of the first sample at which |speed| has stayed below the threshold for
    more than ``duration_s`` [s] (same rule as :class:`ImmobilityMonitor`), or None."""
    monitor = ImmobilityMonitor(speed_threshold_mps, duration_s)
    t = np.asarray(times, dtype=np.float64)
    v = np.asarray(speeds, dtype=np.float64)
    if t.shape != v.shape or t.ndim != 1:
        raise ValueError(f"times and speeds must be equal-length 1-D, got {t.shape}, {v.shape}")
    for i in range(len(t)):
        if monitor.update(t[i], v[i]):
            return i
    return None


def _first_true(flags, n: int) -> int | None:
    if flags is None:
        return None
    f = np.asarray(flags, dtype=bool)
    if f.shape != (n,):
        raise ValueError(f"flags must have shape ({n},), got {f.shape}")
    hits = np.flatnonzero(f)
    return int(hits[0]) if hits.size else None


def evaluate_trial(
    times,
    positions,
    speeds,
    goal,
    flipped=None,
    diverged=None,
    path_found: bool = True,
    goal_tolerance_m: float = GOAL_TOLERANCE_M,
    immobile_speed_mps: float = IMMOBILE_SPEED_MPS,
    immobile_time_s: float = IMMOBILE_TIME_S,
) -> TrialOutcome:
    """Judge a recorded trial: the earliest event decides.

    ``times`` (T,) [s], ``positions`` (T, 2 or 3) [m], ``speeds`` (T,) [m/s],
    ``goal`` (x, y[, …]) [m]; optional boolean ``flipped`` / ``diverged`` (T,).
    Events: reaching the goal (success), immobilized, flipped, diverged. On a
    tie the failure wins. No event by the end of the trace means ``timeout``
    (the loop stops a trial at its time limit). ``path_found=False`` gives
    ``no_path`` without looking at the trace.
    """
    if not path_found:
        return TrialOutcome.failure("no_path")
    t = np.asarray(times, dtype=np.float64)
    p = np.asarray(positions, dtype=np.float64)
    if t.ndim != 1 or len(t) == 0 or p.shape[0] != len(t):
        raise ValueError(f"need T ≥ 1 samples of times and positions, got {t.shape}, {p.shape}")
    g = np.asarray(goal, dtype=np.float64)[:2]
    dist = np.hypot(p[:, 0] - g[0], p[:, 1] - g[1])
    events = [  # (index, priority, reason): failures sort before success on a tie
        (first_immobilized(t, speeds, immobile_speed_mps, immobile_time_s), 0, "immobilized"),
        (_first_true(flipped, len(t)), 0, "flipped"),
        (_first_true(diverged, len(t)), 0, "diverged"),
        (first_goal_reach(p, g, goal_tolerance_m), 1, "success"),
    ]
    happened = [e for e in events if e[0] is not None]
    if not happened:
        return TrialOutcome(False, "timeout", float(t[-1] - t[0]), float(dist[-1]))
    i, _, reason = min(happened)
    return TrialOutcome(reason == "success", reason, float(t[i] - t[0]), float(dist[i]))


# ---------------------------------------------------------------------------
# Success rates with Wilson score intervals
# ---------------------------------------------------------------------------


def wilson_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion k/n::

        p̂ = k/n,  z = Φ⁻¹(1 − α/2),
        (p̂ + z²/2n ± z·√(p̂(1−p̂)/n + z²/4n²)) / (1 + z²/n)

    Returns (low, high) in [0, 1]. E.g. k=16, n=20 → (0.584, 0.919).
    """
    if not (isinstance(n, (int, np.integer)) and isinstance(k, (int, np.integer))):
        raise TypeError(f"k and n must be integers, got {k!r}, {n!r}")
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"need n ≥ 1 and 0 ≤ k ≤ n, got k={k}, n={n}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    z = NormalDist().inv_cdf(1.0 - (1.0 - confidence) / 2.0)
    p = k / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if k == 0 else max(0.0, centre - half)  # exact bounds, not rounding noise
    high = 1.0 if k == n else min(1.0, centre + half)
    return low, high


def success_rows(
    counts: Mapping[str, tuple[int, int]],
    confidence: float = 0.95,
    paper: Mapping[str, int] | None = None,
    paper_n: int | None = None,
) -> list[dict]:
    """One row per method from ``counts`` {method: (k, n)}, in the mapping's order:
    ``method, k, n, sr_pct, ci_low_pct, ci_high_pct`` (percent), plus
    ``paper_k, paper_sr_pct`` when ``paper`` {method: k} and ``paper_n`` are given
    (None for a method the paper lacks)."""
    rows = []
    for method, (k, n) in counts.items():
        lo, hi = wilson_interval(k, n, confidence)
        row = {
            "method": method,
            "k": int(k),
            "n": int(n),
            "sr_pct": 100.0 * k / n,
            "ci_low_pct": 100.0 * lo,
            "ci_high_pct": 100.0 * hi,
        }
        if paper is not None:
            if paper_n is None:
                raise ValueError("paper_n is needed with paper counts")
            pk = paper.get(method)
            row["paper_k"] = pk
            row["paper_sr_pct"] = None if pk is None else 100.0 * pk / paper_n
        rows.append(row)
    return rows


def count_successes(outcomes: Iterable[TrialOutcome]) -> tuple[int, int]:
    """(k, n): successes and trials."""
    outcomes = list(outcomes)
    return sum(o.success for o in outcomes), len(outcomes)


def reason_counts(outcomes: Iterable[TrialOutcome]) -> dict[str, int]:
    """How many trials ended for each reason, in :data:`REASONS` order (zeros kept)."""
    counts = dict.fromkeys(REASONS, 0)
    for o in outcomes:
        counts[o.reason] += 1
    return counts


def markdown_table(
    rows: Sequence[Mapping], title: str | None = None, labels: Mapping[str, str] | None = None
) -> str:
    """A markdown table of :func:`success_rows` output (with the paper's columns when
    the rows carry them). Methods are shown by ``labels`` (default
    :data:`METHOD_LABELS`; unknown keys as they are)."""
    labels = METHOD_LABELS if labels is None else labels
    with_paper = any("paper_k" in r for r in rows)
    head = ["method", "k / n", "SR %", "95 % CI %"]
    if with_paper:
        head += ["paper k", "paper SR %"]
    lines = [] if title is None else [f"**{title}**", ""]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [
            labels.get(r["method"], str(r["method"])),
            f"{r['k']} / {r['n']}",
            f"{r['sr_pct']:.1f}",
            f"{r['ci_low_pct']:.1f}–{r['ci_high_pct']:.1f}",
        ]
        if with_paper:
            pk = r.get("paper_k")
            cells += ["—", "—"] if pk is None else [str(pk), f"{r['paper_sr_pct']:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------
# The paper's numbers (data, for tables beside ours)
# ---------------------------------------------------------------------------

METHODS: tuple[str, ...] = ("dgt_map", "dgt_map_iso", "dgt_map_st", "slope_based", "binary")
"""Method keys; the paper's labels are in :data:`METHOD_LABELS`."""

METHOD_LABELS: dict[str, str] = {
    "dgt_map": "DGT-Map",
    "dgt_map_iso": "DGT-Map (Isotropic)",
    "dgt_map_st": "DGT-Map (Single-Task)",
    "slope_based": "Slope-Based",
    "binary": "Binary",
}


@dataclass(frozen=True)
class PaperResult:
    """One column group of the paper's tables: an environment, its vehicle, n trials and
    the successes k per method."""

    experiment: str
    vehicle: str
    n: int
    k: Mapping[str, int]


# Table I ("Navigation Success Rate on two test maps"): Hill with CarlaCola (n = 20),
# Ridge with MercedesVan (n = 50). Table II ("Navigation Success Rate on Random
# Start-and-Goal Tasks"): Jeep (n = 100) and VolkswagenVan (n = 99).
PAPER_TABLE_I: dict[str, PaperResult] = {
    "hill": PaperResult(
        "hill",
        "carla_cola",
        20,
        {"dgt_map": 16, "dgt_map_iso": 10, "dgt_map_st": 5, "slope_based": 16, "binary": 10},
    ),
    "ridge": PaperResult(
        "ridge",
        "mercedes_van",
        50,
        {"dgt_map": 47, "dgt_map_iso": 45, "dgt_map_st": 14, "slope_based": 26, "binary": 20},
    ),
}
PAPER_TABLE_II: dict[str, PaperResult] = {
    "jeep": PaperResult("random", "jeep", 100, {"dgt_map": 70, "dgt_map_st": 64}),
    "vw_van": PaperResult("random", "vw_van", 99, {"dgt_map": 54, "dgt_map_st": 35}),
}


def paper_rows(result: PaperResult, confidence: float = 0.95) -> list[dict]:
    """The paper's own counts as :func:`success_rows` rows (with Wilson intervals)."""
    return success_rows({m: (k, result.n) for m, k in result.k.items()}, confidence)
