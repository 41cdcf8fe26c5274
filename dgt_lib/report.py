"""The results report of ``dgt reproduce``: tables, figures and recordings of
Experiments 1–3, and the ``experiments`` stage's entry point (:func:`stage_experiments`).

Writes ``results/README.md`` in the profile's data directory — each experiment's table
(ours beside the paper's, with Wilson 95 % intervals), the routes each method planned,
the failure reasons — and beside it the figures: planned paths per method (the paper's
path figure) and success rates.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg", force=False)
import json

import matplotlib.pyplot as plt  # noqa: E402

from dgt_lib import rr, viz
from dgt_lib.core.config import Profile, as_profile, format_setting
from dgt_lib.evaluation import seeds
from dgt_lib.evaluation.experiments import EXPERIMENTS, ExperimentResult
from dgt_lib.evaluation.paper import PAPER
from dgt_lib.learning.training import collapsed_heads
from dgt_lib.mapping.methods import METHOD_LABELS
from dgt_lib.stages.costmaps import ensure_world_costmaps
from dgt_lib.stages.experiments import ensure_experiment
from dgt_lib.stages.paths import data_dir, profile_root
from dgt_lib.stages.registry import StageOutput
from dgt_lib.stages.train import cached_model_metrics
from dgt_lib.world.terrain import get_world

TITLES = {"experiment1": "Experiment 1 — hill, carla_cola (paper Table I, left)",
          "experiment2": "Experiment 2 — ridge, mercedes_van (paper Table I, right)",
          "experiment3": "Experiment 3 — random queries, jeep and vw_van (paper Table II)"}


def _title(prof: Profile) -> str:
    """The profile in a report's title: `` `demo` `` or `` `demo` with planner.beta=50.0``
    (the settings changed by ``--set``, so that a report never passes for the profile's)."""
    name = f"`{prof.name}`"
    return prof.describe().replace(repr(prof.name), name, 1)


def _figures(result: ExperimentResult, prof: Profile, out: Path) -> list[Path]:
    paths = []
    fig = viz.plot_success_rates(result, PAPER.get(result.name))
    paths.append(out / f"{result.name}_success.png")
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)
    labels = sorted({r.task.query.label for r in result.results})
    if result.world in ("hill", "ridge"):
        world = get_world(result.world, prof)
        vehicles = tuple(sorted({r.task.vehicle for r in result.results}))
        maps = ensure_world_costmaps(result.world, vehicles, prof, progress=False)
        fig, axes = plt.subplots(1, len(labels), figsize=(7 * len(labels), 6.5), squeeze=False)
        for ax, label in zip(axes[0], labels, strict=True):
            viz.plot_planned_paths(ax, world, maps, result, label)
        fig.tight_layout()
        paths.append(out / f"{result.name}_paths.png")
        fig.savefig(paths[-1], dpi=90)
        plt.close(fig)
    return paths


def write_results(results: list[ExperimentResult], prof: Profile) -> Path:
    """Write ``results/README.md`` and its figures; returns the markdown's path."""
    out = data_dir(prof) / "results"
    out.mkdir(parents=True, exist_ok=True)
    parts = [f"# Results — profile {_title(prof)}", "",
             "Every number below was measured by `dgt reproduce` on this machine; the paper's "
             "numbers stand beside ours. Intervals are Wilson 95 %.", ""]
    for result in results:
        parts += [f"## {TITLES.get(result.name, result.name)}", "",
                  result.markdown(PAPER.get(result.name)), ""]
        parts += [f"![{p.stem}]({p.name})" for p in _figures(result, prof, out)] + [""]
    path = out / "README.md"
    path.write_text("\n".join(parts))
    return path


def write_recording(result: ExperimentResult, prof: Profile) -> Path:
    """``runs/<name>.rrd`` of an experiment, rewritten when older than its results."""
    out = data_dir(prof)
    rrd = out / "runs" / f"{result.name}.rrd"
    pkl = out / "experiments" / f"{result.name}.pkl"
    if not rrd.exists() or (pkl.exists() and rrd.stat().st_mtime < pkl.stat().st_mtime):
        vehicles = tuple(sorted({r.task.vehicle for r in result.results}))
        maps = ensure_world_costmaps(result.world, vehicles, prof, progress=False)
        rr.log_experiment(result, get_world(result.world, prof), maps, rrd)
    return rrd


def stage_experiments(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: Experiments 1–3 — tables in ``results/``, recordings in
    ``runs/``, and ``results/README.md`` with every table and figure."""
    prof = as_profile(profile)
    paths, parts, results = [], [], []
    for name in EXPERIMENTS:
        res = ensure_experiment(name, prof)
        results.append(res)
        paths.append(write_recording(res, prof))
        counts = ", ".join(f"{METHOD_LABELS[m]} {k}/{n}" for m, (k, n) in res.counts().items())
        parts.append(f"{name}: {counts}")
    paths.insert(0, write_results(results, prof))
    paths.insert(1, write_seed_summary(results, prof))
    return StageOutput(paths, "; ".join(parts))


SUMMARY_RELPATH = "results/summary.json"
"""One seed's summary for the pooled report, under the seed's data directory."""


def write_seed_summary(results: list[ExperimentResult], prof: Profile) -> Path:
    """``results/summary.json`` of the run seed: every experiment's counts and routes, the
    models' test metrics and their collapsed heads (:mod:`dgt_lib.evaluation.seeds`)."""
    models = cached_model_metrics(prof)
    summary = {"seed": prof.seed,
               "overrides": {k: format_setting(v) for k, v in prof.overrides},
               "experiments": {r.name: seeds.experiment_summary(r) for r in results},
               "models": models,
               "collapsed": {kind: collapsed_heads(m) for kind, m in models.items()}}
    path = data_dir(prof) / SUMMARY_RELPATH
    path.write_text(json.dumps(summary, indent=1))
    return path


def seed_summaries(profile: Profile, *, require_all: bool = False) -> list[dict]:
    """The ``results/summary.json`` of each of the profile's seeds that has one (all of
    them, or a FileNotFoundError naming the first missing seed, with ``require_all``)."""
    prof = as_profile(profile)
    summaries = []
    for p in prof.seed_profiles():
        path = data_dir(p) / SUMMARY_RELPATH
        if path.exists():
            summaries.append(json.loads(path.read_text()))
        elif require_all:
            raise FileNotFoundError(f"no results for seed {p.seed} ({path}): run "
                                    f"`dgt reproduce --profile {prof.name}` first")
    return summaries


def write_seeds_report(profile: Profile) -> Path:
    """``data/<profile>/results/README.md``: every experiment over the profile's seeds —
    k/n per seed, pooled with its Wilson interval, the spread — the claims per seed and
    the models' test errors, from each seed's ``results/summary.json``."""
    prof = as_profile(profile)
    summaries = seed_summaries(prof, require_all=True)
    ids = [s["seed"] for s in summaries]
    parts = [f"# Results — profile {_title(prof)}, {len(ids)} seed(s): "
             + ", ".join(map(str, ids)), "",
             "Every number below was measured by `dgt reproduce` on this machine. Per method: "
             "k/n in each seed, the pooled k/n with its Wilson 95 % interval, and the spread "
             "(lowest–highest success rate of the seeds); the paper's k/n beside ours. Each "
             "seed's own report, with figures: "
             + ", ".join(f"[seed {s}](../seed-{s}/results/README.md)" for s in ids) + ".", "",
             "## Claims, seed by seed", "", seeds.claims_table(summaries)]
    for name in EXPERIMENTS:
        parts += [f"## {TITLES.get(name, name)}", "",
                  seeds.experiment_over_seeds(summaries, name, PAPER.get(name))]
    parts += ["## Learned locomotion (test split)", "", seeds.learning_table(summaries)]
    out = profile_root(prof) / "results"
    out.mkdir(parents=True, exist_ok=True)
    path = out / "README.md"
    path.write_text("\n".join(parts))
    return path
