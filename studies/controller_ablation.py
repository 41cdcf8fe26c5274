"""Experiments 1–3 with each trials' controller, side by side: success, how the others
ended, and the mean cost of the driven paths, pooled over run seeds.

    .venv/bin/python studies/controller_ablation.py --profile demo --seeds 3
    .venv/bin/python studies/controller_ablation.py --profile demo --seed 0 --seed 4
    .venv/bin/python studies/controller_ablation.py --profile demo --seeds 3 --hazard \\
        --out docs/controller_ablation.md

Reads the cached experiments of ``dgt reproduce --seed S --set experiments.controller=NAME``
(``--hazard``: with ``experiments.eval_hazard_world=true`` too, Experiment 3 on
``eval_hazard``); it runs nothing, and names each missing one with the command that makes it.
The driven cost is :func:`dgt_lib.evaluation.driven_cost.driven_cost` on the vehicle's
DGT-Map costmap — one yardstick for every method and controller. It also lists every failed
DGT-Map trial of Experiment 1 (where, when, why), the ones the page must explain.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np

from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import CONTROLLERS
from dgt_lib.evaluation.driven_cost import driven_cost
from dgt_lib.evaluation.experiments import EXPERIMENTS, ExperimentResult
from dgt_lib.evaluation.statistics import wilson_interval
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS
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
                     profile: str) -> str:
    """Markdown: one row per (vehicle, method, controller), pooled over the seeds given."""
    seed_of = {id(r): seed for runs in by_controller.values() for seed, res in runs
               for r in res.results}

    def dgt_cost(r) -> float:
        prof = get_profile(profile).with_(seed=seed_of[id(r)])
        maps = trial_maps(r.task.world, "dgt", r.task.vehicle, prof)
        return driven_cost(r.trajectory, maps.costmap("dgt", r.task.vehicle), maps.grid)

    first = [res for _, res in next(iter(by_controller.values()))]
    world = first[0].world
    seeds = ", ".join(str(seed) for seed, _ in next(iter(by_controller.values())))
    lines = [f"**{name}** ({world}, {profile}, seeds pooled: {seeds})", "",
             "| vehicle | method | controller | arrived (SR, 95 %) | immobilized | flipped "
             "| other | driven cost |", "|---|---|---|---|---|---|---|---|"]
    vehicles = sorted({r.task.vehicle for res in first for r in res.results})
    for vehicle in vehicles:
        for method in METHODS:
            for controller, runs in by_controller.items():
                rs = [r for _, res in runs for r in res.results
                      if r.task.vehicle == vehicle and r.task.method == method]
                if rs:
                    cells = row_cells(rs, dgt_cost)
                    lines.append(f"| {vehicle} | {METHOD_LABELS[method]} | {controller} | "
                                 + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def failures(runs: dict[str, list[tuple[int, ExperimentResult]]], method: str = "dgt"
             ) -> str:
    """Markdown list of every failed trial of ``method``: seed, query, route, how and where."""
    lines = []
    for controller, seeded in runs.items():
        for seed, res in seeded:
            index: Counter = Counter()
            for r in res.results:
                label = r.task.query.label
                if r.task.method == method and not r.outcome.success:
                    end = r.trajectory[-1, 1:3] if len(r.trajectory) else (np.nan, np.nan)
                    lines.append(f"- {controller}, seed {seed}, {label} #{index[label]} "
                                 f"(route {r.route}): {r.outcome.reason} after "
                                 f"{r.outcome.duration_s:.1f} s at ({end[0]:.1f}, {end[1]:.1f}) m")
                if r.task.method == method:
                    index[label] += 1
    return "\n".join(lines) or "- none"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="demo")
    which = ap.add_mutually_exclusive_group()
    which.add_argument("--seeds", type=int, default=3, help="run seeds 0 … N-1")
    which.add_argument("--seed", type=int, action="append", default=None,
                       help="these run seeds instead (repeatable)")
    ap.add_argument("--controller", action="append", choices=CONTROLLERS, default=None,
                    help="controllers to compare (default: all)")
    ap.add_argument("--hazard", action="store_true",
                    help="Experiment 3 on eval_hazard (experiments.eval_hazard_world=true)")
    ap.add_argument("--experiment", action="append", choices=list(EXPERIMENTS), default=None)
    ap.add_argument("--out", type=Path, default=None, help="also write the tables here")
    args = ap.parse_args()
    controllers = args.controller or list(CONTROLLERS)
    names = args.experiment or (["experiment3"] if args.hazard else list(EXPERIMENTS))
    seeds = args.seed or list(range(args.seeds))
    parts = []
    for name in names:
        seeded = {c: [(s, res) for s in seeds
                      if (res := stored(name, s, args.profile, c, args.hazard)) is not None]
                  for c in controllers}
        if not all(seeded.values()) or len({len(v) for v in seeded.values()}) != 1:
            print(f"{name}: not every controller has every seed; skipped")
            continue
        parts.append(experiment_table(name, seeded, args.profile))
        if name == "experiment1":
            parts.append("Failed DGT-Map trials of experiment1:\n\n" + failures(seeded) + "\n")
    text = "\n".join(parts)
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
