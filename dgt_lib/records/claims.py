"""The paper's claims, each checked over a run's seeds with a stated rule.

A claim about *routes* (DGT-Map plans carla_cola's ascents by Route A) holds in a seed
when every plan takes that route (:data:`dgt_lib.evaluation.seeds.CLAIMS`); it is
**reproduced** when it holds in every seed. A claim that one method *arrives more often*
than another compares the pooled arrivals k/n of the seeds: **reproduced** when the two
Wilson 95 % intervals are disjoint with the first higher, **a tie** when they overlap,
**reversed** when they are disjoint the other way. A claim that two methods do *as well*
as each other is reproduced when their intervals overlap. Every rule is applied by code,
so a verdict in the README changes only when the records do.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from dgt_lib.evaluation.statistics import n_seeds, wilson_interval
from dgt_lib.mapping.methods import METHOD_LABELS

Record = dict
"""One seed's run record (:mod:`dgt_lib.records.record`)."""


def pooled(records: Sequence[Record], experiment: str, vehicle: str, method: str
           ) -> tuple[int, int] | None:
    """(arrivals, trials) of ``method`` for ``vehicle`` in ``experiment`` summed over the
    seeds' records; None where no record has it."""
    kn = [r["experiments"].get(experiment, {}).get("counts", {}).get(vehicle, {}).get(method)
          for r in records]
    kn = [x for x in kn if x is not None]
    return (sum(k for k, _ in kn), sum(n for _, n in kn)) if kn else None


def compare(a: tuple[int, int], b: tuple[int, int]) -> str:
    """``higher``, ``lower`` or ``tie``: a's pooled rate against b's by their Wilson 95 %
    intervals (disjoint or overlapping)."""
    (alo, ahi), (blo, bhi) = wilson_interval(*a), wilson_interval(*b)
    if alo > bhi:
        return "higher"
    if ahi < blo:
        return "lower"
    return "tie"


@dataclass(frozen=True)
class Verdict:
    """What a run measured for a claim (``measured``, Markdown) and whether it reproduces
    the paper's (``reproduced``: True, False, or None where the run cannot tell)."""

    measured: str
    reproduced: bool | None
    note: str = ""

    @property
    def word(self) -> str:
        """**reproduced** / **not reproduced** / — , with the rule's note."""
        word = {True: "**reproduced**", False: "**not reproduced**", None: "—"}[self.reproduced]
        return f"{word}: {self.note}" if self.note else word


def route_claim(claim: str) -> Callable[[Sequence[Record]], Verdict]:
    """A route claim of :data:`~dgt_lib.evaluation.seeds.CLAIMS`, over seeds."""
    def check(records: Sequence[Record]) -> Verdict:
        checks = [r.get("claims", {}).get(claim) for r in records]
        checks = [c for c in checks if c and c[1] > 0]
        if not checks:
            return Verdict("not measured", None)
        held = sum(bool(c[2]) for c in checks)
        plans = f"{sum(c[0] for c in checks)}/{sum(c[1] for c in checks)} plans"
        return in_every_seed(held, len(checks), f" ({plans})")
    return check


def in_every_seed(held: int, seeds: int, detail: str = "") -> Verdict:
    """A claim that holds only when it held in every one of ``seeds``: ``held`` of them."""
    of = f"{held} of {n_seeds(seeds)}"
    return Verdict(of + detail, held == seeds, "" if held == seeds else f"in {of}")


def more_claim(experiment: str, vehicle: str, method: str, others: Sequence[str]
               ) -> Callable[[Sequence[Record]], Verdict]:
    """``method`` arrives more often than each of ``others`` (pooled, Wilson 95 %)."""
    def check(records: Sequence[Record]) -> Verdict:
        a = pooled(records, experiment, vehicle, method)
        bs = [pooled(records, experiment, vehicle, o) for o in others]
        if a is None or any(b is None for b in bs):
            return Verdict("not measured", None)
        measured = f"{a[0]}/{a[1]} vs " + ", ".join(f"{b[0]}/{b[1]}" for b in bs)
        outcome = [compare(a, b) for b in bs]
        if all(o == "higher" for o in outcome):
            return Verdict(measured, True)
        notes = [f"{'a tie with' if o == 'tie' else 'below'} {METHOD_LABELS[m]}"
                 for m, o in zip(others, outcome, strict=True) if o != "higher"]
        return Verdict(measured, False, ", ".join(notes) + " (Wilson 95 % intervals)")
    return check


def same_claim(experiment: str, vehicle: str, method: str, other: str
               ) -> Callable[[Sequence[Record]], Verdict]:
    """``method`` arrives as often as ``other``: their intervals overlap."""
    def check(records: Sequence[Record]) -> Verdict:
        a, b = (pooled(records, experiment, vehicle, m) for m in (method, other))
        if a is None or b is None:
            return Verdict("not measured", None)
        outcome = compare(a, b)
        note = "" if outcome == "tie" else f"{METHOD_LABELS[method]} {outcome}, intervals apart"
        return Verdict(f"{a[0]}/{a[1]} vs {b[0]}/{b[1]}", outcome == "tie", note)
    return check


def closer_claim(vehicle: str | None) -> Callable[[Sequence[Record]], Verdict]:
    """The multi-task costmap significantly closer to the measured ground truth than the
    single-task one, for ``vehicle`` (every vehicle for None), in every seed."""
    def check(records: Sequence[Record]) -> Verdict:
        scored = [r["multitask"] for r in records if r.get("multitask")]
        if not scored:
            return Verdict("not measured", None)
        def holds(comparisons) -> bool:
            mine = [c for c in comparisons if vehicle is None or c["vehicle"] == vehicle]
            return bool(mine) and all(c["closer"] == "multi-task" for c in mine)
        return in_every_seed(sum(holds(c) for c in scored), len(scored))
    return check


@dataclass(frozen=True)
class Claim:
    """One of the paper's claims (or one of ours, ``ours=True``): its text, the paper's
    own numbers, a short name for the bottom line, and the rule that checks it."""

    text: str
    paper: str
    short: str
    check: Callable[[Sequence[Record]], Verdict]
    ours: bool = False


CLAIMS: tuple[Claim, ...] = (
    Claim("Exp. 1: DGT-Map plans carla_cola's ascents by Route A (the gentle way up)",
          "shown in its path figure", "up the hill by the gentle route",
          route_claim("hill_ascent_A")),
    Claim("Exp. 1: …and its descents by the steep Route B", "shown in its path figure",
          "down by the steep one", route_claim("hill_descent_B")),
    Claim("Exp. 1: DGT-Map arrives more often than DGT-Map(Iso) and Binary",
          "16 vs 10, 10 of 20", "more arrivals than the isotropic and binary maps on the hill",
          more_claim("experiment1", "carla_cola", "dgt", ("isotropic", "binary"))),
    Claim("Exp. 1: …and than DGT-Map(ST)", "16 vs 5 of 20",
          "more arrivals than the single-task map on the hill",
          more_claim("experiment1", "carla_cola", "dgt", ("single-task",))),
    Claim("Exp. 1: Slope-Based does as well as DGT-Map", "16 and 16 of 20",
          "Slope-Based as good as DGT-Map on the hill",
          same_claim("experiment1", "carla_cola", "slope", "dgt")),
    Claim("Exp. 2: DGT-Map plans the mercedes_van across the smoothed section",
          "shown in its path figure", "the van round by the smoothed section",
          route_claim("ridge_smooth")),
    Claim("Exp. 2: the jeep's DGT-Map plans cross the sharp ridge directly",
          "in its text, not its tables", "the jeep straight across the sharp ridge",
          route_claim("ridge_jeep_sharp")),
    Claim("Exp. 2: DGT-Map arrives more often than Slope-Based and Binary",
          "47 vs 26, 20 of 50", "more arrivals than Slope-Based and binary on the ridge",
          more_claim("experiment2", "mercedes_van", "dgt", ("slope", "binary"))),
    Claim("Exp. 2: …and than DGT-Map(ST)", "47 vs 14 of 50",
          "more arrivals than the single-task map on the ridge",
          more_claim("experiment2", "mercedes_van", "dgt", ("single-task",))),
    Claim("Exp. 3: multi-task DGT-Map arrives more often than single-task, jeep",
          "70 vs 64 of 100", "multi-task beating single-task for the jeep",
          more_claim("experiment3", "jeep", "dgt", ("single-task",))),
    Claim("Exp. 3: …and for the vw_van", "54 vs 35 of 99",
          "multi-task beating single-task for the vw_van",
          more_claim("experiment3", "vw_van", "dgt", ("single-task",))),
    Claim("Exp. 3: the learned costmap beats occupancy alone (Binary) for the vw_van",
          "—", "the learned map beating occupancy alone for the vw_van",
          more_claim("experiment3", "vw_van", "dgt", ("binary",)), ours=True),
    Claim("Sharing data helps the vehicle with least data: carla_cola's multi-task map "
          "closer to the driven ground truth than its single-task map", "—",
          "shared data helping carla_cola's map", closer_claim("carla_cola"), ours=True),
    Claim("…for every vehicle", "—", "shared data helping every vehicle's map",
          closer_claim(None), ours=True),
)
"""The claims the README's table checks, in its order."""
