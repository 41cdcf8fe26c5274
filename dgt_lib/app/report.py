"""The results report of ``dgt reproduce``: tables, figures and recordings of
Experiments 1–3: the ``experiments`` stage's report step (:func:`report_stage`).

Writes ``results/README.md`` in the profile's data directory — each experiment's table
(ours beside the paper's, with Wilson 95 % intervals), the routes each method planned,
the failure reasons, and every costmap's accuracy against the measured ground truth
(the ``ground_truth`` stage, :mod:`dgt_lib.stages.ground_truth`) — and beside it the
figures: planned paths per method (the paper's path figure), success rates, where the
failed trials ended (marker by reason), and the ground truth on the learned layers.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt

from dgt_lib import viz
from dgt_lib.core.config import Profile, as_profile
from dgt_lib.evaluation.experiments import EXPERIMENT_TITLES, ExperimentResult
from dgt_lib.evaluation.paper import PAPER
from dgt_lib.records import tables
from dgt_lib.records.record import seed_summaries, write_seed_record
from dgt_lib.stages.costmaps import ensure_world_costmaps
from dgt_lib.stages.ground_truth import (
    accuracy_markdown,
    cached_costmap_accuracy,
    ensure_ground_truth,
)
from dgt_lib.stages.output import StageOutput
from dgt_lib.stages.paths import profile_root, results_dir
from dgt_lib.viz import recording
from dgt_lib.world.terrain import get_world


def _title(prof: Profile) -> str:
    """The profile in a report's title: `` `demo` `` or `` `demo` with planner.beta=50.0``
    (the settings changed by ``--set``, so that a report never passes for the profile's)."""
    name = f"`{prof.name}`"
    return prof.describe().replace(repr(prof.name), name, 1)


def _save(fig: plt.Figure, path: Path, dpi: int) -> Path:
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def _figures(result: ExperimentResult, prof: Profile, out: Path) -> list[Path]:
    matplotlib.use("Agg", force=False)  # off-screen when the report draws, not on import
    world = get_world(result.world, prof)
    paths = [_save(viz.plot_success_rates(result, PAPER.get(result.name)),
                   out / f"{result.name}_success.png", 90),
             _save(viz.plot_failure_map(world, result, queries=result.world == "eval"),
                   out / f"{result.name}_failures.png", 80)]
    labels = sorted({r.task.query.label for r in result.results})
    if result.world in ("hill", "ridge"):
        vehicles = tuple(sorted({r.task.vehicle for r in result.results}))
        maps = ensure_world_costmaps(result.world, vehicles, prof, progress=False)
        fig, axes = plt.subplots(1, len(labels), figsize=(7 * len(labels), 6.5), squeeze=False)
        for ax, label in zip(axes[0], labels, strict=True):
            viz.plot_planned_paths(ax, world, maps, result, label)
        fig.tight_layout()
        paths.append(_save(fig, out / f"{result.name}_paths.png", 90))
    return paths


ACCURACY_TITLE = "Costmap accuracy against the measured ground truth (open loop)"
ACCURACY_INTRO = (
    "Each vehicle an experiment uses drove straight through sampled cells of the hill, ridge "
    "and eval worlds at the K headings, at the commanded 5 m/s with the collection's speed "
    "controller, and L* was computed with the paper's formula in the 1 s window centred on "
    "the crossing (`dgt_lib.evaluation.ground_truth`; measured once per profile, the same "
    "for every seed). Each method's cost C = 1 − L̂ is scored against C* = 1 − L* on the "
    "measured samples of free cells: MAE, Spearman ρ, and the directional contrast "
    "|C(θ) − C(θ+π)| over opposite headings whose C* differs by more than 0.3, with how "
    "often the method makes the harder direction the costlier one (same sign).")
ACCURACY_FIGURES = (("hill", "carla_cola"), ("ridge", "mercedes_van"))
"""The (world, vehicle) whose ground truth the report draws on the learned layers."""


def _accuracy_section(prof: Profile, out: Path) -> list[str]:
    """The report's accuracy section (tables and figures), or a line saying how to get it."""
    result = cached_costmap_accuracy(prof)
    parts = [f"## {ACCURACY_TITLE}", ""]
    if result is None:
        return parts + ["Not measured for this seed: run `dgt reproduce --stages "
                        "ground_truth` (it runs before the experiments).", ""]
    parts += [ACCURACY_INTRO, "", accuracy_markdown(result)]
    matplotlib.use("Agg", force=False)  # off-screen when the report draws, not on import
    for world, vehicle in ACCURACY_FIGURES:
        truth = ensure_ground_truth(world, vehicle, prof, progress=False)
        maps = ensure_world_costmaps(world, (vehicle,), prof, progress=False)
        path = _save(viz.plot_ground_truth_beside_layers(get_world(world, prof), maps, truth),
                     out / f"accuracy_{world}.png", 80)
        parts.append(f"![{path.stem}]({path.name})")
    return parts + [""]


def write_results(results: list[ExperimentResult], prof: Profile) -> Path:
    """Write ``results/README.md`` and its figures; returns the markdown's path."""
    out = results_dir(prof)
    out.mkdir(parents=True, exist_ok=True)
    parts = [f"# Results — profile {_title(prof)}", "",
             "Every number below was measured by `dgt reproduce` on this machine; the paper's "
             "numbers stand beside ours. Intervals are Wilson 95 %.", ""]
    for result in results:
        parts += [f"## {EXPERIMENT_TITLES.get(result.name, result.name)}", "",
                  result.markdown(PAPER.get(result.name)), ""]
        parts += [f"![{p.stem}]({p.name})" for p in _figures(result, prof, out)] + [""]
    parts += _accuracy_section(prof, out)
    path = out / "README.md"
    path.write_text("\n".join(parts))
    return path


def report_stage(name: str, profile: Profile, output: StageOutput) -> StageOutput:
    """The report step of a stage with ``report`` set (:mod:`dgt_lib.stages.registry`),
    run by ``dgt reproduce`` after it: for ``experiments``, every experiment's recording
    in ``runs/``, ``results/README.md`` with every table and figure, and the seed's run
    record ``results/summary.json`` (:mod:`dgt_lib.records.record`); returns the stage's
    output with what it wrote first."""
    if name != "experiments":
        raise ValueError(f"no report step for stage {name!r}")
    prof = as_profile(profile)
    results = output.value
    paths = [write_results(results, prof), write_seed_record(results, prof)]
    paths += [recording.experiment_recording(res, prof) for res in results]
    return StageOutput(paths + output.paths, output.summary)


def seed_results(seed: int, output: StageOutput, later: list[int]) -> str:
    """What ``dgt reproduce`` prints when one seed's experiments are done and ``later``
    seeds are still to run: the claims checked in that seed
    (:data:`~dgt_lib.evaluation.seeds.CLAIMS`: count/total, ✓ where it holds), its
    arrivals and its report (``output``: :func:`report_stage`'s)."""
    from dgt_lib.evaluation.seeds import CLAIMS

    summary = next((p for p in output.paths if p.name == "summary.json"), None)
    claims = json.loads(summary.read_text())["claims"] if summary else {}  # none if unwritten
    follow = (f"seeds {', '.join(map(str, later))} follow" if len(later) > 1
              else f"seed {later[0]} follows")
    lines = [f"── seed {seed}'s results ({follow}; the verdicts pooled over every seed come "
             "after the last):"]
    lines += [f"   {'✓' if ok else '✗'} {CLAIMS[name][0]}: {k}/{n}"
              for name, (k, n, ok) in claims.items() if n]
    lines.append(f"   arrivals: {output.summary}")
    if summary:
        lines.append(f"   report: {summary.with_name('README.md')}")
    return "\n".join(lines)


def write_seeds_report(profile: Profile) -> Path:
    """``data/<profile>/results/README.md``: every experiment over the profile's seeds —
    k/n per seed, pooled with its Wilson interval, the spread — the claims per seed, the
    models' test errors and the costmaps' accuracy against the ground truth, from each
    seed's ``results/summary.json``."""
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
             tables.seeds_sections(tables.Run(prof.name, tuple(summaries)), published=False)]
    out = profile_root(prof) / "results"
    out.mkdir(parents=True, exist_ok=True)
    path = out / "README.md"
    path.write_text("\n".join(parts))
    return path
