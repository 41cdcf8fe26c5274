"""Experiments 1–3 with each trials' controller, side by side: success, how the others
ended, and the mean cost of the driven paths, pooled over run seeds.

    .venv/bin/python studies/controller_ablation.py --profile demo --seeds 3
    .venv/bin/python studies/controller_ablation.py --profile demo --seed 0 --seed 4
    .venv/bin/python studies/controller_ablation.py --profile demo --seeds 3 --hazard --publish
    .venv/bin/python studies/controller_ablation.py --profile demo --seeds 8 --controller paper \\
        --experiment experiment1 --publish      # the canonical run's hill, by route

Reads the cached experiments of ``dgt reproduce --seed S --set experiments.controller=NAME``
(``--hazard``: with ``experiments.eval_hazard_world=true`` too, Experiment 3 on
``eval_hazard``); it runs nothing, and names each missing one with the command that makes it.
The driven cost is :func:`dgt_lib.evaluation.driven_cost.driven_cost` on the vehicle's
DGT-Map costmap — one yardstick for every method and controller. It also lists every failed
DGT-Map trial of Experiment 1 (where, when, why), the ones the page must explain, and a
summary of the arrivals by controller. ``--publish`` writes the record that
docs/controller_ablation.md and docs/controller.md quote.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
from runner import Study

from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import CONTROLLERS
from dgt_lib.evaluation.driven_cost import driven_cost
from dgt_lib.evaluation.experiments import EXPERIMENTS, ExperimentResult
from dgt_lib.evaluation.statistics import wilson_interval
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS
from dgt_lib.records.study import table
from dgt_lib.stages.experiments import (
    experiment_path,
    reproduce_command,
    stored_experiment,
    trial_maps,
)

FAILURE_COLUMNS = ("immobilized", "flipped")
"""Failure reasons with a column of their own; the rest are summed as 'other'."""


def stored(name: str, seed: int, profile: str, controller: str, hazard: bool
           ) -> ExperimentResult | None:
    """A cached experiment of one run seed and controller, or None (with the command)."""
    overrides: dict[str, object] = {"experiments.controller": controller}
    if hazard:
        overrides["experiments.eval_hazard_world"] = True
    prof = get_profile(profile).with_(seed=seed).with_overrides(overrides)
    result = stored_experiment(name, prof)
    if result is None:
        print(f"missing: {experiment_path(name, prof)}\n  {reproduce_command(prof)}")
    return result


def row_cells(results: list, dgt_cost) -> list[str]:
    """Table cells of one method's trials: k/n (SR %, Wilson 95 %), immobilized, flipped,
    other failures, mean driven cost."""
    n, k = len(results), sum(r.outcome.success for r in results)
    lo, hi = wilson_interval(k, n)
    why = Counter(r.outcome.reason for r in results if not r.outcome.success)
    other = sum(v for reason, v in why.items() if reason not in FAILURE_COLUMNS)
    costs = [dgt_cost(r) for r in results if len(r.trajectory) > 1]
    costs = [c for c in costs if np.isfinite(c)]
    mean = f"{np.mean(costs):.3f}" if costs else "–"
    return [f"{k}/{n} ({100 * k / n:.0f} %, {100 * lo:.0f}–{100 * hi:.0f})",
            *(str(why[reason]) for reason in FAILURE_COLUMNS), str(other), mean]


def experiment_table(name: str, by_controller: dict[str, list[tuple[int, ExperimentResult]]],
                     profile: str) -> dict:
    """One row per (vehicle, method, controller), pooled over the seeds given."""
    seed_of = {id(r): seed for runs in by_controller.values() for seed, res in runs
               for r in res.results}

    def dgt_cost(r) -> float:
        prof = get_profile(profile).with_(seed=seed_of[id(r)])
        maps = trial_maps(r.task.world, "dgt", r.task.vehicle, prof)
        return driven_cost(r.trajectory, maps.costmap("dgt", r.task.vehicle), maps.grid)

    first = [res for _, res in next(iter(by_controller.values()))]
    rows = []
    for vehicle in sorted({r.task.vehicle for res in first for r in res.results}):
        for method in METHODS:
            for controller, runs in by_controller.items():
                rs = [r for _, res in runs for r in res.results
                      if r.task.vehicle == vehicle and r.task.method == method]
                if rs:
                    rows.append([vehicle, METHOD_LABELS[method], controller,
                                 *row_cells(rs, dgt_cost)])
    return table(f"{name} ({first[0].world})",
                 ["vehicle", "method", "controller", "arrived (SR, 95 %)", "immobilized",
                  "flipped", "other", "driven cost"], rows)


def by_seed(name: str, by_controller: dict[str, list[tuple[int, ExperimentResult]]]) -> dict:
    """Arrivals k/n seed by seed: one row per (vehicle, method, controller), one column per
    run seed (what a table pooled over the seeds hides)."""
    seeds = [seed for seed, _ in next(iter(by_controller.values()))]
    first = [res for _, res in next(iter(by_controller.values()))]
    rows = []
    for vehicle in sorted({r.task.vehicle for res in first for r in res.results}):
        for method in METHODS:
            for controller, runs in by_controller.items():
                cells = []
                for _, res in runs:
                    rs = [r for r in res.results
                          if r.task.vehicle == vehicle and r.task.method == method]
                    cells.append(f"{sum(r.outcome.success for r in rs)}/{len(rs)}")
                if any(not c.endswith("/0") for c in cells):
                    rows.append([vehicle, METHOD_LABELS[method], controller, *cells])
    return table(f"{name} ({first[0].world}), arrivals k/n seed by seed",
                 ["vehicle", "method", "controller", *(f"seed {s}" for s in seeds)], rows)


def arrivals_by_controller(tables: dict[str, dict], controllers: list[str]) -> dict:
    """The experiments' arrivals side by side: one row per (experiment, vehicle, method),
    one column per controller, k/n pooled over the seeds."""
    rows = []
    for key, tab in tables.items():
        if key.endswith("_seeds"):
            continue
        cells: dict[tuple[str, str], dict[str, str]] = {}
        for vehicle, method, controller, arrived, *_ in tab["rows"]:
            cells.setdefault((vehicle, method), {})[controller] = arrived.split(" ")[0]
        for (vehicle, method), by in cells.items():
            rows.append([tab["title"], vehicle, method, *(by.get(c, "–") for c in controllers)])
    return table("arrivals by controller, k/n",
                 ["experiment", "vehicle", "method", *(f"`{c}`" for c in controllers)], rows)


def by_route(runs: dict[str, list[tuple[int, ExperimentResult]]]) -> dict:
    """Experiment 1's arrivals by the route each plan took, k/n per method and for every
    method together: what tells the maps' choice of route from the controller's driving."""
    rows = []
    for controller, seeded in runs.items():
        trials = [r for _, res in seeded for r in res.results]
        for label, route in sorted({(r.task.query.label, r.route or "–") for r in trials}):
            cells = []
            for method in (*METHODS, None):
                rs = [r for r in trials if r.task.query.label == label and (r.route or "–") == route
                      and method in (None, r.task.method)]
                cells.append(f"{sum(r.outcome.success for r in rs)}/{len(rs)}" if rs else "–")
            rows.append([controller, f"{label}s by Route {route}", *cells])
    return table("arrivals by route, k/n",
                 ["controller", "plans", *(METHOD_LABELS[m] for m in METHODS), "every method"],
                 rows)


def failures(runs: dict[str, list[tuple[int, ExperimentResult]]], method: str = "dgt"
             ) -> str:
    """Every failed trial of ``method``: seed, query, route, how and where, a line each."""
    lines = []
    for controller, seeded in runs.items():
        for seed, res in seeded:
            index: Counter = Counter()
            for r in res.results:
                label = r.task.query.label
                if r.task.method == method and not r.outcome.success:
                    end = r.trajectory[-1, 1:3] if len(r.trajectory) else (np.nan, np.nan)
                    lines.append(f"{controller}, seed {seed}, {label} #{index[label]} "
                                 f"(route {r.route}): {r.outcome.reason} after "
                                 f"{r.outcome.duration_s:.1f} s at ({end[0]:.1f}, {end[1]:.1f}) m")
                if r.task.method == method:
                    index[label] += 1
    return lines


def main() -> None:
    study = Study("controller_ablation", __doc__)
    study.parser.add_argument("--controller", action="append", choices=CONTROLLERS,
                              default=None, help="controllers to compare (default: all)")
    study.parser.add_argument("--hazard", action="store_true",
                              help="Experiment 3 on eval_hazard "
                                   "(experiments.eval_hazard_world=true)")
    study.parser.add_argument("--experiment", action="append", choices=list(EXPERIMENTS),
                              default=None)
    args = study.parse()
    controllers = args.controller or list(CONTROLLERS)
    names = args.experiment or (["experiment3"] if args.hazard else list(EXPERIMENTS))
    tables, lists, routes = {}, {}, None
    for name in names:
        seeded = {c: [(s, res) for s in study.seeds
                      if (res := stored(name, s, args.profile, c, args.hazard)) is not None]
                  for c in controllers}
        if not all(seeded.values()) or len({len(v) for v in seeded.values()}) != 1:
            print(f"{name}: not every controller has every seed; skipped")
            continue
        tables[name] = experiment_table(name, seeded, args.profile)
        if len(study.seeds) > 1:
            tables[f"{name}_seeds"] = by_seed(name, seeded)
        if name == "experiment1":
            lists["experiment1_failures"] = failures(seeded)
            routes = by_route(seeded)
    if tables:
        tables["arrivals"] = arrivals_by_controller(tables, controllers)
    if routes:
        tables["experiment1_routes"] = routes
    variant = "-".join(filter(None, ["hazard" if args.hazard else "",
                                     "+".join(args.controller or [])]))
    study.finish(tables, lists, variant=variant)


if __name__ == "__main__":
    main()
