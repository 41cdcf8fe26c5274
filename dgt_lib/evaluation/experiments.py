"""The paper's three experiments and their tables (paper: Experiments, Results).

* Experiment 1 — hill, carla_cola, ascents and descents: does the planner pick
  Route A uphill and Route B downhill?
* Experiment 2 — ridge, mercedes_van: does it cross at the smoothed section?
  ``experiment2_jeep`` (ours) drives the jeep on the same queries: the other half of the
  paper's vehicle claim, that a jeep crosses the sharp ridge the long, low van cannot.
* Experiment 3 — eval world, random start–goal pairs, jeep and vw_van:
  multi-task vs single-task, with Binary (occupancy only, a zero costmap) as the floor
  that shows how much any costmap matters on these queries. The eval world is the
  training world's generator from another seed (:mod:`dgt_lib.world.terrain`); a query
  is kept only when its straight segment start → goal crosses at least
  ``ExperimentsConfig.eval_min_hazard_m`` of cells that one of the experiment's vehicles
  cannot cross, judged from the world's true heights and the vehicles' specifications
  (slope above the max climb, or a crest above the ground clearance between the axles;
  :mod:`dgt_lib.evaluation.hazards`), and when Hybrid A* finds a kinematically feasible
  path for it (:func:`~dgt_lib.evaluation.queries.draw_random_queries`). The rule is
  fixed in advance and sees no learned costmap and no method's outcome.

Each is a set of closed-loop trials (:mod:`dgt_lib.evaluation.trials`) on identical
queries for every method; :class:`ExperimentResult` turns them into the paper's tables
(with Wilson 95 % intervals), the routes each method planned and the failure reasons.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dgt_lib.core.config import Profile, as_profile
from dgt_lib.evaluation.hazards import hazard_map
from dgt_lib.evaluation.queries import Query, hill_queries, random_queries, ridge_queries
from dgt_lib.evaluation.statistics import markdown_table, reason_counts, success_rows
from dgt_lib.evaluation.trials import MapsLoader, TrialResult, run_trials, trial_tasks
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS
from dgt_lib.world.terrain import get_world


@dataclass
class ExperimentResult:
    """All trials of an experiment, with their tables."""

    name: str
    world: str
    results: list[TrialResult]

    def counts(self, vehicle: str | None = None, label: str | None = None
               ) -> dict[str, tuple[int, int]]:
        """{method: (k, n)} in the paper's method order."""
        out = {}
        for m in METHODS:
            rs = [r for r in self.results if r.task.method == m
                  and (vehicle is None or r.task.vehicle == vehicle)
                  and (label is None or r.task.query.label == label)]
            if rs:
                out[m] = (sum(r.outcome.success for r in rs), len(rs))
        return out

    def table(self, vehicle: str, paper=None) -> str:
        """A markdown table like the paper's (k, n, SR %) with Wilson 95 % intervals and,
        when given, the paper's numbers beside ours."""
        rows = success_rows(self.counts(vehicle), paper=None if paper is None else dict(paper.k),
                            paper_n=None if paper is None else paper.n)
        return markdown_table(rows, title=f"{self.name}: {vehicle}")

    def routes(self) -> dict[tuple[str, str], dict[str, int]]:
        """{(method, label): {route: count}} — which way each method planned."""
        out: dict[tuple[str, str], dict[str, int]] = {}
        for r in self.results:
            d = out.setdefault((r.task.method, r.task.query.label), {})
            route = r.route or ("no path" if len(r.path) == 0 else "—")
            d[route] = d.get(route, 0) + 1
        return out

    def reasons(self) -> dict[str, dict[str, int]]:
        """{method: {reason: count}}."""
        return {m: reason_counts(r.outcome for r in self.results if r.task.method == m)
                for m in METHODS if any(r.task.method == m for r in self.results)}

    def route_markdown(self) -> str:
        """Markdown table: the routes each method planned, per query label."""
        lines = ["| method | query | planned routes |", "|---|---|---|"]
        for (m, label), d in sorted(self.routes().items(),
                                    key=lambda kv: (METHODS.index(kv[0][0]), kv[0][1])):
            lines.append(f"| {METHOD_LABELS[m]} | {label} | "
                         + ", ".join(f"{k}: {v}" for k, v in sorted(d.items())) + " |")
        return "\n".join(lines) + "\n"

    def reason_markdown(self) -> str:
        """Markdown table: how the trials of each method ended."""
        reasons = self.reasons()
        names = list(next(iter(reasons.values()), {}))
        lines = ["| method | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        for m, d in reasons.items():
            lines.append(f"| {METHOD_LABELS[m]} | " + " | ".join(str(v) for v in d.values())
                         + " |")
        return "\n".join(lines) + "\n"

    def markdown(self, paper: dict | None = None) -> str:
        """Tables (ours beside the paper's), routes and failure reasons as markdown."""
        vehicles = sorted({r.task.vehicle for r in self.results})
        parts = [self.table(v, (paper or {}).get(v)) for v in vehicles]
        if any(r.route for r in self.results):
            parts.append(self.route_markdown())
        return "\n".join(parts + [self.reason_markdown()])


EXPERIMENTS: dict[str, tuple[str, tuple[str, ...], tuple[str, ...]]] = {
    "experiment1": ("hill", ("carla_cola",), METHODS),
    "experiment2": ("ridge", ("mercedes_van",), METHODS),
    "experiment2_jeep": ("ridge", ("jeep",), METHODS),
    "experiment3": ("eval", ("jeep", "vw_van"), ("dgt", "single-task", "binary")),
}
"""Each experiment's world, vehicles and methods (paper: Experiments 1–3;
``experiment2_jeep``: Experiment 2's queries for the jeep, which the paper's text claims
but its table does not measure)."""


EXPERIMENT_TITLES: dict[str, str] = {
    "experiment1": "Experiment 1 — hill, carla_cola (paper Table I, left)",
    "experiment2": "Experiment 2 — ridge, mercedes_van (paper Table I, right)",
    "experiment2_jeep": "Experiment 2 for the jeep — the same ridge queries (ours)",
    "experiment3": "Experiment 3 — random queries, jeep and vw_van (paper Table II)"}
"""Each experiment's heading in reports and docs."""


def experiment_world(name: str, profile: Profile) -> str:
    """The world experiment ``name`` runs on: :data:`EXPERIMENTS`' own, except that
    Experiment 3 runs on ``eval_hazard`` with ``ExperimentsConfig.eval_hazard_world``."""
    if name == "experiment3" and profile.experiments.eval_hazard_world:
        return "eval_hazard"
    return EXPERIMENTS[name][0]


def experiment_queries(name: str, profile: Profile, load_maps: MapsLoader
                       ) -> dict[str, list[Query]]:
    """The queries of an experiment per vehicle, at the profile's n, from its seed."""
    prof, ex = profile, profile.experiments
    world = experiment_world(name, prof)
    if name == "experiment1":
        return {"carla_cola": hill_queries(get_world(world, prof), ex.n_hill, ex, prof.seed)}
    if name in ("experiment2", "experiment2_jeep"):  # the same queries for each vehicle
        return {v: ridge_queries(get_world(world, prof), ex.n_ridge, ex, prof.seed)
                for v in EXPERIMENTS[name][1]}
    hazards = hazard_map(get_world(world, prof), EXPERIMENTS[name][1])
    return {v: random_queries(load_maps(world, "binary", v, prof), n, ex, prof.seed, v,
                              hazards=hazards, planner_cfg=prof.planner)
            for v, n in (("jeep", ex.n_eval_jeep), ("vw_van", ex.n_eval_vw_van))}


def run_experiment(name: str, profile: Profile | str | None = None, *,
                   load_maps: MapsLoader, progress: bool = True,
                   journal: str | Path | None = None) -> ExperimentResult:
    """Run experiment ``"experiment1"`` (hill), ``"experiment2"`` (ridge) or
    ``"experiment3"`` (eval, random pairs) at the profile's n.

    load_maps: where trials get their costmaps (see :mod:`dgt_lib.evaluation.trials`;
    :func:`dgt_lib.stages.experiments.trial_maps` reads the artifact cache).
    journal: see :func:`run_trials` (finished trials are kept there; a rerun resumes).
    """
    if name not in EXPERIMENTS:
        raise ValueError(f"unknown experiment {name!r}; valid: {', '.join(EXPERIMENTS)}")
    prof = as_profile(profile)
    _, vehicles, methods = EXPERIMENTS[name]
    world = experiment_world(name, prof)
    queries = experiment_queries(name, prof, load_maps)
    for v in vehicles:  # build every costmap here first, so that workers only load them
        for m in methods:
            load_maps(world, m, v, prof)
    tasks = [t for v in vehicles
             for t in trial_tasks(name, world, v, queries[v], methods, prof)]
    results = run_trials(tasks, load_maps, workers=prof.workers, progress=progress,
                         journal=journal, backend=prof.execution.executor,
                         address=prof.execution.address)
    return ExperimentResult(name, world, results)
