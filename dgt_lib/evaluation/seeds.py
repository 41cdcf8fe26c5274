"""Conclusions over seeds: per seed, pooled with a Wilson interval, and the spread.

Physics is not bit-identical across machines, so one run's success counts are one draw;
a claim stands only if it holds across seeds. Each seed's experiments are summarised as
plain JSON-able dicts (:func:`experiment_summary`), then pooled here:

- per method: k/n in every seed, the pooled k/n with its Wilson 95 % interval, and the
  spread (lowest–highest success rate of the seeds);
- the directional and vehicle claims, checked per seed (:data:`CLAIMS`): DGT-Map's
  carla_cola plans climb the hill by Route A; DGT-Map's mercedes_van plans cross the
  ridge at the smoothed section; no head of any model has collapsed; and, against the
  measured ground truth (:mod:`dgt_lib.evaluation.accuracy`), the multi-task costmap is
  closer to it than the single-task one for every vehicle (Claim 4 without the closed
  loop).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

from dgt_lib.evaluation.experiments import ExperimentResult
from dgt_lib.evaluation.paper import PaperResult
from dgt_lib.evaluation.statistics import n_seeds, wilson_interval
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS

Summary = dict
"""One seed's summary: ``{"seed", "experiments": {name: experiment_summary}, "models":
{kind: {vehicle: metrics}}, "collapsed": {kind: [vehicle, …]}, "accuracy": [row, …] or
None, "multitask": [comparison, …] or None}`` (rows of
:func:`dgt_lib.evaluation.accuracy.costmap_accuracy` with ``world``, ``vehicle``,
``method``; comparisons of :func:`dgt_lib.evaluation.accuracy.multitask_comparisons`)."""


def experiment_summary(result: ExperimentResult) -> dict:
    """The counts of one experiment as JSON-able dicts: ``counts`` {vehicle: {method:
    [k, n]}}, ``routes`` {method: {label: {route: count}}}, ``reasons`` {method: {reason:
    count}}."""
    vehicles = sorted({r.task.vehicle for r in result.results})
    routes: dict[str, dict[str, dict[str, int]]] = {}
    for (method, label), d in result.routes().items():
        routes.setdefault(method, {})[label] = dict(d)
    return {"world": result.world,
            "counts": {v: {m: list(kn) for m, kn in result.counts(v).items()} for v in vehicles},
            "routes": routes, "reasons": result.reasons()}


def pooled_rows(per_seed: Sequence[Mapping[str, Sequence[int]]]) -> list[dict]:
    """Rows per method (in the paper's order) from ``[{method: (k, n)}, …]`` (one dict per
    seed): ``method``, ``per_seed`` [(k, n) or None], ``k``, ``n``, ``sr_pct``,
    ``ci_low_pct``, ``ci_high_pct`` (Wilson 95 % of the pooled k/n), ``spread_pct``
    (lowest, highest success rate of the seeds)."""
    rows = []
    for m in METHODS:
        seeds = [tuple(d[m]) if m in d else None for d in per_seed]
        have = [kn for kn in seeds if kn is not None]
        if not have:
            continue
        k, n = sum(kn[0] for kn in have), sum(kn[1] for kn in have)
        lo, hi = wilson_interval(k, n)
        rates = [100.0 * a / b for a, b in have]
        rows.append({"method": m, "per_seed": seeds, "k": k, "n": n, "sr_pct": 100.0 * k / n,
                     "ci_low_pct": 100.0 * lo, "ci_high_pct": 100.0 * hi,
                     "spread_pct": (min(rates), max(rates))})
    return rows


def pooled_table(rows: Sequence[dict], seeds: Sequence[int], paper: PaperResult | None = None,
                 title: str | None = None) -> str:
    """Markdown: k/n per seed, pooled k/n, its Wilson interval, the spread, the paper's."""
    head = ["method", *[f"seed {s}" for s in seeds], "pooled k / n", "SR %", "95 % CI %",
            "spread %"] + (["paper"] if paper else [])
    lines = [] if title is None else [f"**{title}**", ""]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [METHOD_LABELS[r["method"]]]
        cells += ["—" if kn is None else f"{kn[0]}/{kn[1]}" for kn in r["per_seed"]]
        cells += [f"{r['k']} / {r['n']}", f"{r['sr_pct']:.0f}",
                  f"{r['ci_low_pct']:.0f}–{r['ci_high_pct']:.0f}",
                  f"{r['spread_pct'][0]:.0f}–{r['spread_pct'][1]:.0f}"]
        if paper:
            pk = paper.k.get(r["method"])
            cells.append("—" if pk is None else f"{pk}/{paper.n}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def experiment_over_seeds(summaries: Sequence[Summary], name: str,
                          paper: Mapping[str, PaperResult] | None = None) -> str:
    """Markdown: one :func:`pooled_table` per vehicle of experiment ``name`` over the
    seeds' summaries (``paper``: the paper's results per vehicle, or None)."""
    per_vehicle: dict[str, list] = {}
    for s in summaries:
        for v, counts in s["experiments"].get(name, {}).get("counts", {}).items():
            per_vehicle.setdefault(v, []).append(counts)
    ids = [s["seed"] for s in summaries]
    return "\n".join(pooled_table(pooled_rows(per_seed), ids, (paper or {}).get(v), title=v)
                     for v, per_seed in per_vehicle.items())


def _route_share(summary: Summary, experiment: str, method: str, label: str | None,
                 route: str) -> tuple[int, int]:
    """(plans that took ``route``, plans) of ``method`` in an experiment, over one label
    (or every label for None)."""
    routes = summary["experiments"].get(experiment, {}).get("routes", {}).get(method, {})
    labels = [label] if label is not None else list(routes)
    chosen = sum(routes.get(lab, {}).get(route, 0) for lab in labels)
    total = sum(sum(routes.get(lab, {}).values()) for lab in labels)
    return chosen, total


def _multitask_closer(summary: Summary) -> tuple[int, int]:
    """(vehicles whose multi-task costmap is significantly closer to the ground truth than
    its single-task one, vehicles compared) in one seed; (0, 0) without the comparison."""
    comparisons = summary.get("multitask") or []
    return sum(c["closer"] == "multi-task" for c in comparisons), len(comparisons)


CLAIMS: dict[str, tuple[str, Callable[[Summary], tuple[int, int]]]] = {
    "no_collapse": ("no head of any model collapsed (models with a collapsed head / models)",
                    lambda s: (sum(bool(v) for v in s["collapsed"].values()),
                               len(s["collapsed"]))),
    "hill_ascent_A": ("DGT-Map's carla_cola ascents planned by Route A",
                      lambda s: _route_share(s, "experiment1", "dgt", "ascent", "A")),
    "hill_descent_B": ("DGT-Map's carla_cola descents planned by Route B (the paper's; "
                       "not a claim of ours)",
                       lambda s: _route_share(s, "experiment1", "dgt", "descent", "B")),
    "ridge_smooth": ("DGT-Map's mercedes_van plans crossing at the smoothed section",
                     lambda s: _route_share(s, "experiment2", "dgt", None, "smooth")),
    "ridge_jeep_sharp": ("DGT-Map's jeep plans crossing the sharp ridge directly, on the "
                         "same queries (the paper's text; not in its tables)",
                         lambda s: _route_share(s, "experiment2_jeep", "dgt", None, "sharp")),
    "multitask_closer": ("vehicles whose multi-task costmap is closer to the measured ground "
                         "truth than its single-task one (MAE lower by ≥ 0.005, paired test "
                         "p < 0.05; Claim 4 without the closed loop)",
                         _multitask_closer),
}
"""The claims checked in every seed: (description, summary → (count, out of))."""


def claim_holds(name: str, count: int, total: int) -> bool:
    """Whether a claim holds in one seed: every plan as claimed (no collapsed model for
    ``no_collapse``); False when there is nothing to check."""
    if name == "no_collapse":
        return total > 0 and count == 0
    return total > 0 and count == total


def claims_table(summaries: Sequence[Summary]) -> str:
    """Markdown: each claim of :data:`CLAIMS`, its count per seed, and whether it held."""
    head = ["claim", *[f"seed {s['seed']}" for s in summaries], "holds in"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, (text, count) in CLAIMS.items():
        cells, held = [text], 0
        for s in summaries:
            k, n = count(s)
            ok = claim_holds(name, k, n)
            held += ok
            cells.append(f"{k}/{n} {'✓' if ok else '✗'}" if n else "—")
        cells.append(f"{held} of {n_seeds(len(summaries))}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def learning_table(summaries: Sequence[Summary]) -> str:
    """Markdown: test MSE and Spearman ρ of each model's heads per seed, COLLAPSED marked."""
    lines = ["| seed | model | " + " | ".join(["head: MSE / ρ / std(L̂)÷std(L)"]) + " |",
             "|---|---|---|"]
    for s in summaries:
        for kind, metrics in s["models"].items():
            parts = []
            for v, m in metrics.items():
                ratio = m.get("pred_std", float("nan")) / max(m.get("label_std", 0.0), 1e-12)
                flag = " **COLLAPSED**" if v in s["collapsed"].get(kind, []) else ""
                parts.append(f"{v} {m['mse']:.3f} / {m['spearman']:.2f} / {ratio:.2f}{flag}")
            lines.append(f"| {s['seed']} | {kind} | " + "; ".join(parts) + " |")
    return "\n".join(lines) + "\n"
