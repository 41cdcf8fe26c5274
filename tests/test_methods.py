"""One vocabulary for the compared methods: code uses the keys of ``METHODS``, everything a
reader sees — figure legends, titles and ticks, report tables, notebooks, the README —
their labels ``METHOD_LABELS`` (the paper's Table I)."""

import re
import subprocess
import types
from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dgt_lib import viz  # noqa: E402
from dgt_lib.evaluation.experiments import ExperimentResult  # noqa: E402
from dgt_lib.evaluation.paper import PAPER  # noqa: E402
from dgt_lib.evaluation.queries import Query  # noqa: E402
from dgt_lib.evaluation.trials import TrialResult, TrialTask  # noqa: E402
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS  # noqa: E402
from dgt_lib.navigation.outcome import TrialOutcome  # noqa: E402
from dgt_lib.world.worlds import from_heightmap  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
LABELS = set(METHOD_LABELS.values())
OLD_NAMES = re.compile(r"DGT-Map ?\((?:Isotropic|Single-[Tt]ask)\)|DGT-Map \((?:Iso|ST)\)"
                       r"|\| (?:Iso|Single-task|Slope|Bin) \|")
"""Names the methods went by before: the paper's long forms, spaced forms, table shorthands."""


def _hill_like_result() -> ExperimentResult:
    """Every method on one query of a 40 m × 40 m world: a path, a driven track, an outcome."""
    query = Query((5.0, 5.0, 0.0), (30.0, 30.0), "ascent")
    path = np.column_stack([np.linspace(5, 30, 20), np.linspace(5, 30, 20), np.zeros(20)])
    track = np.column_stack([np.linspace(0, 10, 20), path[:, 0], path[:, 1], np.zeros(20)])
    results = []
    for i, m in enumerate(METHODS):
        task = TrialTask("experiment1", "hill", m, "carla_cola", query, 0, "smoke", 0)
        outcome = (TrialOutcome(True, "success", 9.0) if i % 2 == 0
                   else TrialOutcome.failure("immobilized", 12.0))
        results.append(TrialResult(task, outcome, path=path, route="AB"[i % 2],
                                   trajectory=track, speed=np.full(20, 5.0)))
    return ExperimentResult("experiment1", "hill", results)


def _label_of(text: str) -> str:
    """The method label a legend entry or tick starts with (the longest that fits)."""
    return max((label for label in LABELS if text.startswith(label)), key=len, default=text)


def test_figures_name_every_method_by_its_label():
    result = _hill_like_result()
    world = from_heightmap(np.zeros((100, 100), np.float32), 0.4, name="flat")
    maps = types.SimpleNamespace(occupancy=np.zeros(world.grid.shape, np.uint8),
                                 grid=world.grid)
    fig, ax = plt.subplots()
    viz.plot_planned_paths(ax, world, maps, result, "ascent")
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert [_label_of(t) for t in legend] == [METHOD_LABELS[m] for m in METHODS]
    speeds = viz.plot_trial_speeds(result)
    assert [a.get_title() for a in speeds.axes] == [METHOD_LABELS[m] for m in METHODS]
    rates = viz.plot_success_rates(result, PAPER["experiment1"])
    ticks = [t.get_text() for t in rates.axes[0].get_xticklabels()]
    assert ticks == [METHOD_LABELS[m] for m in METHODS]
    plt.close("all")


def test_report_tables_name_every_method_by_its_label():
    text = _hill_like_result().markdown(PAPER["experiment1"])
    rows = [line.split("|")[1].strip() for line in text.splitlines()
            if line.startswith("| ") and not line.startswith("| method")]
    assert rows and set(rows) == LABELS
    assert not any(re.search(rf"\| {re.escape(key)} \|", text) for key in METHODS)


def _documents() -> list[Path]:
    names = subprocess.run(["git", "ls-files", "*.md", "*.ipynb", "*.py"], cwd=ROOT,
                           capture_output=True, text=True).stdout.split()
    return [ROOT / n for n in names if not n.startswith("tests/")]


@pytest.mark.skipif(not (ROOT / ".git").exists(), reason="needs a git checkout")
def test_no_document_uses_an_old_name_of_a_method():
    offenders = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in _documents()
                 for m in OLD_NAMES.finditer(p.read_text())]
    assert offenders == []


def _trial(method: str, outcome: TrialOutcome, track_end: tuple[float, float] | None,
           index: int = 0) -> TrialResult:
    """One Experiment 3 trial from (5, 5) whose driven track ends at ``track_end`` (no
    track for None)."""
    query = Query((5.0, 5.0, 0.0), (35.0, 30.0), "random")
    task = TrialTask("experiment3", "eval", method, "vw_van", query, index, "smoke", 0)
    if track_end is None:
        return TrialResult(task, outcome)
    xy = np.column_stack([np.linspace(5, track_end[0], 10), np.linspace(5, track_end[1], 10)])
    track = np.column_stack([np.linspace(0, 9, 10), xy, np.zeros(10)])
    return TrialResult(task, outcome, trajectory=track, speed=np.full(10, 5.0))


def test_failure_figures_mark_where_each_failed_trial_ended_by_reason():
    results = [_trial("dgt", TrialOutcome(True, "success", 9.0), (34.0, 30.0)),
               _trial("binary", TrialOutcome.failure("immobilized", 20.0), (12.0, 7.5), 1),
               _trial("single-task", TrialOutcome.failure("flipped", 5.0), (20.0, 17.0), 2),
               _trial("binary", TrialOutcome.failure("no_path"), None, 3)]
    result = ExperimentResult("experiment3", "eval", results)
    world = from_heightmap(np.zeros((100, 100), np.float32), 0.4, name="flat")
    fig = viz.plot_failure_map(world, result, queries=True)
    ax = fig.axes[0]
    marks = {}
    for coll in ax.collections:
        for xy in coll.get_offsets():
            marks[(round(float(xy[0]), 3), round(float(xy[1]), 3))] = coll
    assert set(marks) == {(12.0, 7.5), (20.0, 17.0), (5.0, 5.0)}  # not the success's end
    # one marker shape per reason: the immobilized, flipped and no-path ends differ
    paths = {k: tuple(map(tuple, c.get_paths()[0].vertices.round(3))) for k, c in marks.items()}
    assert len(set(paths.values())) == 3
    [failure_legend] = ax.artists
    legend = [t.get_text() for t in failure_legend.get_texts()]
    assert {"immobilized (1)", "flipped (1)", "no path (1)"} <= set(legend)
    assert {METHOD_LABELS["binary"], METHOD_LABELS["single-task"]} <= set(legend)
    plt.close("all")


def test_the_path_figure_marks_the_failed_trials_of_its_query():
    results = [_trial("dgt", TrialOutcome(True, "success", 9.0), (34.0, 30.0)),
               _trial("binary", TrialOutcome.failure("immobilized", 20.0), (12.0, 7.5))]
    result = ExperimentResult("experiment3", "eval", results)
    world = from_heightmap(np.zeros((100, 100), np.float32), 0.4, name="flat")
    maps = types.SimpleNamespace(occupancy=np.zeros(world.grid.shape, np.uint8), grid=world.grid)
    fig, ax = plt.subplots()
    viz.plot_planned_paths(ax, world, maps, result, "random")
    ends = [tuple(np.round(xy, 3)) for c in ax.collections for xy in c.get_offsets()]
    assert ends == [(12.0, 7.5)]
    plt.close("all")
