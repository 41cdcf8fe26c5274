"""The notebooks' graded exercises: the grader accepts the library's own answer, catches
each common mistake with its hint, and tells an unanswered exercise apart from a wrong one."""

import importlib.util
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from dgt_lib import exercises
from dgt_lib.exercises import EXERCISES, NOT_ANSWERED, RIGHT, WRONG, check, grade, plug


def _lstsq_plane(points):
    a = np.column_stack([np.ones(len(points)), points[:, :2]])
    return tuple(np.linalg.lstsq(a, points[:, 2], rcond=None)[0])


def _sq(x):
    return x * x


def _hazard_m(mask, origin, res, start, goal, *, swap=False, wrap=False):
    """Hazard metres on the straight line, optionally with one of two mistakes."""
    (sx, sy), (gx, gy) = start[:2], goal[:2]
    d = np.hypot(gx - sx, gy - sy)
    t = np.linspace(0, 1, max(2, int(np.ceil(d / (res / 2))) + 1))
    c = np.floor((sx + t * (gx - sx) - origin[0]) / res).astype(int)
    r = np.floor((sy + t * (gy - sy) - origin[1]) / res).astype(int)
    if swap:
        r, c = c, r
    if wrap:  # a negative index reads the far edge
        return d * np.mean(mask[r % mask.shape[0], c % mask.shape[1]])
    on = (r >= 0) & (r < mask.shape[0]) & (c >= 0) & (c < mask.shape[1])
    return d * np.mean(np.where(on, mask[np.clip(r, 0, mask.shape[0] - 1),
                                         np.clip(c, 0, mask.shape[1] - 1)], False))


# One deliberate mistake per exercise, and the words its hint must contain. (The right
# answers are the reference solutions in notebooks/solutions/, graded below.)
LEARNER_WRONG = {
    "cell_plane": (lambda p: (p[:, 2].mean(), *_lstsq_plane(p)[1:]), "cell centre"),
    "locomotion": (lambda d, dt: np.exp(-_sq((5.0 - d) / 5.0) * 4.5), "divide by it"),
    "masked_loss": (lambda p, y, h: ((p - y[:, None]) ** 2).mean(), "only the head"),
    "heading_bin": (lambda t, k: (np.mod(t, 2 * np.pi) // (2 * np.pi / k)).astype(int) % k,
                    "nearest bin"),
    "edge_cost": (lambda s, c, b: s * (1 + c + b * c), "super-linear"),
    "slope_locomotion": (lambda t, t0, lo, hi, pu, pd: 1 - np.clip(
        np.abs(t - t0) / (hi - t0), 0, 1) ** pu, "downhill"),
    "hazard_length": (lambda *a: _hazard_m(*a, wrap=True), "off the map"),
    "changed_mask": (lambda oc, oo, nc, no: no.copy() if oc is None
                     else np.any(oc != nc, axis=0), "observed flags too"),
    "contrast_pairs": (lambda c, v, th: np.nonzero(
        np.abs(c[:, 4:] - c[:, :4]) > th), "both samples"),
    "trial_outcome": (lambda d, imm, done, t, limit: (
        "success" if d <= 5.0 else "flipped" if done else "immobilized" if imm >= 10.0
        else "timeout" if t >= limit else "driving"), "exactly 10 s"),
    "mppi_weights": (lambda s, lam: (lambda e: e / e.sum())(np.exp(-s / lam)), "min S"),
    "mean_command": (lambda t, v, a, b: np.array([  # the commands sent in the window, averaged
        v[(t >= x) & (t <= y)].mean() for x, y in zip(a, b, strict=True)]), "holds"),
}

# More mistakes, each caught by the case meant for it.
MORE_MISTAKES = [
    ("hazard_length", lambda *a: _hazard_m(*a, swap=True), "rows run along y"),
    ("hazard_length", lambda m, o, r, s, g: _hazard_m(m, (0.0, 0.0), r, s, g), "origin"),
    ("hazard_length", lambda m, o, r, s, g: _hazard_m(m, o, 1.0, s, g), "grid's Δ"),
    ("hazard_length", lambda *a: _hazard_m(*a) / max(np.hypot(a[4][0] - a[3][0],
                                                              a[4][1] - a[3][1]), 1e-9),
     "metres = d"),
    ("changed_mask", lambda oc, oo, nc, no: no.copy() if oc is None else
     (oo != no) | ~np.isclose(oc, nc, atol=0.01).all(axis=0), "even by a millimetre"),
    ("changed_mask", lambda oc, oo, nc, no: no.copy() if oc is None else
     (oo != no) | (oc[3] != nc[3]), "all six channels"),
    ("changed_mask", lambda oc, oo, nc, no: np.ones_like(no) if oc is None else
     (oo != no) | np.any(oc != nc, axis=0), "first frame"),
]


NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"
SOLUTIONS = sorted((NOTEBOOKS / "solutions").glob("*.py"))


def _cells(stem):
    nb = json.loads((NOTEBOOKS / f"{stem}.ipynb").read_text())
    return nb["cells"]


def _exercise_cells(name):
    cells = {c.get("id"): "".join(c["source"]) for c in _cells(EXERCISES[name].notebook)}
    return [cells.get(f"exercise-{name}-{part}") for part in ("task", "answer", "check")]


def _answer_function(name):
    """The name of the function the notebook's answer cell asks the learner to write."""
    return re.search(r"^def (\w+)\(", _exercise_cells(name)[1], re.M).group(1)


def _load(path):
    spec = importlib.util.spec_from_file_location(f"solution_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _unanswered(*args):
    raise NotImplementedError


def test_every_exercise_names_a_notebook_that_exists():
    for name, ex in EXERCISES.items():
        assert (NOTEBOOKS / f"{ex.notebook}.ipynb").exists(), name


@pytest.mark.parametrize("number", [f"{i:02d}" for i in range(1, 13)])
def test_every_notebook_asks_an_exercise_and_checks_it(number):
    paths = sorted(NOTEBOOKS.glob(f"{number}_*.ipynb"))
    if not paths:
        pytest.skip(f"no notebook {number}")
    cells = _cells(paths[0].stem)
    checks = [re.search(r'check\("(\w+)"', "".join(c["source"])) for c in cells
              if c["cell_type"] == "code" and str(c.get("id", "")).startswith("exercise-")]
    names = [m.group(1) for m in checks if m]
    assert names, f"{paths[0].name} has no exercise cell that calls check"
    assert all(EXERCISES[n].notebook == paths[0].stem for n in names)


@pytest.mark.parametrize("path", SOLUTIONS, ids=lambda p: p.name)
def test_every_solution_is_right(path, capsys):
    names = [n for n, ex in EXERCISES.items() if ex.notebook == path.stem]
    assert names, f"{path.name}: no exercise of notebook {path.stem} in EXERCISES"
    module = _load(path)
    assert capsys.readouterr().out == "", "a solution file prints nothing at import"
    for name in names:
        result = grade(name, getattr(module, _answer_function(name)))
        assert result.status == RIGHT, result.message


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_reference_passes_its_own_check(name):
    assert grade(name, EXERCISES[name].reference).status == RIGHT


@pytest.mark.parametrize("name, wrong, words",
                         [(n, *LEARNER_WRONG[n]) for n in sorted(LEARNER_WRONG)] + MORE_MISTAKES)
def test_a_wrong_answer_is_reported_with_its_hint(name, wrong, words):
    result = grade(name, wrong)
    assert result.status == WRONG
    assert words in result.hint, result.message
    assert result.message.startswith("wrong: ")


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_an_unanswered_exercise_shows_the_reference_instead_of_failing(name):
    for learner in (_unanswered, lambda *args: None):
        result = grade(name, learner)
        assert result.status == NOT_ANSWERED
        assert result.message.startswith("not answered yet")
        assert "reference gives" in result.message


def test_check_prints_the_verdict(capsys):
    check("edge_cost", lambda s, c, b: s * (1 + c + b * c * c))
    check("edge_cost", LEARNER_WRONG["edge_cost"][0])
    check("edge_cost", _unanswered)
    lines = [ln for ln in capsys.readouterr().out.splitlines() if not ln.startswith(" ")]
    assert [ln.split(" ")[0] for ln in lines] == ["right", "wrong:", "not"]


def test_an_exception_in_the_learners_code_is_a_wrong_answer():
    result = grade("locomotion", lambda d, dt: math.exp(-((5 * dt - d) / (5 * dt)) ** 2 * 4.5))
    assert result.status == WRONG  # math.exp cannot take the array case
    assert "TypeError" in result.message and "arrays" in result.hint


def test_a_half_answered_function_is_wrong_not_unanswered():
    def partly(theta, k):
        if np.ndim(theta):
            return None
        return np.round(np.mod(theta, 2 * np.pi) / (2 * np.pi / k)).astype(int) % k

    assert grade("heading_bin", partly).status == WRONG


def test_the_learner_cannot_change_the_inputs_the_reference_sees():
    def clobber(points):
        points[:, 2] = 0.0
        return exercises.EXERCISES["cell_plane"].reference(points)

    assert grade("cell_plane", clobber).status == WRONG


def test_an_unknown_exercise_names_the_known_ones():
    with pytest.raises(KeyError, match="locomotion"):
        grade("no_such_exercise", _unanswered)


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_each_notebook_ships_its_exercise_unanswered_and_checked(name, capsys):
    task, answer, check_cell = _exercise_cells(name)
    assert task and "$$" in task, "state the task with its equation"
    assert answer and "raise NotImplementedError" in answer, "ship the answer unanswered"
    assert check_cell and f'check("{name}"' in check_cell
    namespace = {}
    exec(answer, namespace)  # noqa: S102 — the notebook's own cells, as a learner runs them
    exec(check_cell, namespace)  # noqa: S102
    assert capsys.readouterr().out.startswith("not answered yet")


def test_plug_hands_the_pipeline_the_learners_function_once_answered(capsys):
    def wrong(s, c, b):
        return s * (1 + c)

    assert plug("edge_cost", _unanswered) is EXERCISES["edge_cost"].reference
    assert plug("edge_cost", wrong) is wrong  # a wrong answer shows its effect downstream
    lines = capsys.readouterr().out.splitlines()
    assert "library's reference" in lines[0] and "your function (wrong)" in lines[1]


PLUGGED = ("cell_plane", "locomotion", "slope_locomotion", "hazard_length", "contrast_pairs",
           "changed_mask")
"""Exercises whose notebook runs part of the pipeline with the learner's function."""


@pytest.mark.parametrize("name", PLUGGED)
def test_the_check_cell_is_followed_by_pipeline_cells_that_use_the_learners_function(name):
    cells = _cells(EXERCISES[name].notebook)
    ids = [c.get("id") for c in cells]
    after = cells[ids.index(f"exercise-{name}-check") + 1:]
    code = ["".join(c["source"]) for c in after if c["cell_type"] == "code"]
    found = re.search(rf'^(\w+) = plug\("{name}", {_answer_function(name)}\)$', code[0], re.M)
    assert found, f"the cell after {name}'s check plugs the learner's function in"
    used = re.compile(rf"\b{found.group(1)}\b")
    assert any(used.search(c) for c in code[1:]), "a later cell runs the pipeline with it"


# The hooks the plugged exercises use: with the library's own function (or none) they give
# the library's result to the bit; with another function, that function's.
def test_locomotion_signal_applies_the_label_it_is_given():
    from dgt_lib.perception.locomotion import locomotion, locomotion_signal

    t = np.arange(0.0, 6.0, 0.04)
    xy = np.column_stack([5.0 * t - 0.3 * t**2, np.zeros_like(t)])
    library = locomotion_signal(t, xy)
    assert np.array_equal(locomotion_signal(t, xy, label=locomotion), library)
    speed = locomotion_signal(t, xy, label=lambda d, dt: d / dt)  # [m/s] over each window
    assert np.allclose(speed[75], 5.0 - 0.6 * t[75], atol=1e-9)
    assert not np.allclose(locomotion_signal(t, xy, label=lambda d, dt: 0 * d), library)


def test_slope_costmap_runs_the_locomotion_it_is_given():
    from dgt_lib.core.geometry import GridSpec
    from dgt_lib.mapping.baselines import SlopeModel, slope_costmap
    from tests.test_costmap import synthetic_bev

    x, _ = GridSpec((0.0, 0.0), 0.4, (50, 50)).cell_centers()
    bev = synthetic_bev((0.3 * x).astype(np.float32))
    van = SlopeModel(theta0=0.0, theta_min=-0.6, theta_max=0.25, p_u=1.0, p_d=2.0)
    library = slope_costmap(bev, [van], 4, progress=False)
    same = slope_costmap(bev, [van], 4, locomotion=EXERCISES["slope_locomotion"].reference,
                         progress=False)
    flat = slope_costmap(bev, [van], 4, locomotion=lambda t, *m: np.ones_like(t),
                         progress=False)
    assert np.array_equal(same, library)
    assert flat[:, :, bev.observed].max() < library[:, :, bev.observed].max()


def test_costmap_accuracy_counts_the_pairs_it_is_given():
    from dgt_lib.evaluation.accuracy import contrast_pairs, costmap_accuracy

    rng = np.random.default_rng(1)
    truth, cost = rng.uniform(0, 1, (30, 8)), rng.uniform(0, 1, (30, 8))
    valid = rng.uniform(0, 1, (30, 8)) > 0.2
    library = costmap_accuracy(truth, cost, valid)
    assert costmap_accuracy(truth, cost, valid, select_pairs=contrast_pairs) == library
    one = costmap_accuracy(truth, cost, valid,
                           select_pairs=lambda *a: (np.array([0]), np.array([1])))
    assert one["pairs"] == 1 and one["mae"] == library["mae"]


def test_the_hazard_rule_measures_with_the_function_it_is_given():
    from dataclasses import replace

    from dgt_lib.core.geometry import GridSpec
    from dgt_lib.evaluation.hazards import HazardMap

    mask = np.zeros((20, 30), bool)
    mask[:, 10:14] = True
    hazards = HazardMap(GridSpec((-3.0, 1.0), 0.5, mask.shape), mask)
    start, goal = (-2.0, 5.0, 0.3), (11.0, 6.0)
    sampled = hazards.length_m(start, goal)
    assert 1.9 < sampled < 2.2  # 2 m of hazard, crossed at a slant, sampled every 0.25 m
    assert replace(hazards, measure=lambda *a: 7.0).length_m(start, goal) == 7.0


# ----------------------------------------------------------------------------- answers shown late
SHOWN_SOURCE = re.compile(r"\b(?:getsource|source_markdown|show_source)\(\s*([\w.]+)")
GENERIC = {"GridSpec", "BEVMap"}
"""Names an exercise's reference uses that give nothing of its answer away."""


def _reference_names(name):
    """The library functions and classes exercise ``name`` is graded against: the adapter's
    own name and what it imports or names in its docstring (``:func:``/``:class:``)."""
    import inspect

    source = inspect.getsource(EXERCISES[name].reference)
    names = {EXERCISES[name].reference.__name__.lstrip("_")}
    for imported in re.findall(r"^\s*from \S+ import (.+)$", source, re.M):
        names |= {n.strip() for n in imported.split(",")}
    names |= {r.split(".")[-1] for r in re.findall(r":(?:func|class):`~?([\w.]+)`", source)}
    return names - GENERIC


def _shows(expression, names):
    """Whether displaying ``expression``'s source shows one of ``names``: its last part (a
    function) or any capitalised part (a class, e.g. ``SlopeModel.locomotion``)."""
    parts = expression.split(".")
    return parts[-1] in names or any(p[:1].isupper() and p in names for p in parts)


def test_reference_names_are_the_librarys_functions():
    assert {"edge_cost", "amplified_cost"} <= _reference_names("edge_cost")
    assert "SlopeModel" in _reference_names("slope_locomotion")
    assert "mppi_weights" in _reference_names("mppi_weights")
    assert _shows("SlopeModel.locomotion", _reference_names("slope_locomotion"))
    assert not _shows("locomotion.locomotion_signal", _reference_names("locomotion"))


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_no_notebook_shows_an_exercises_answer_before_its_check(name):
    """The library's source of an exercise's function is shown after the check cell, never
    before it: not earlier in its notebook, not in an earlier notebook."""
    names, own = _reference_names(name), EXERCISES[name].notebook
    early = []
    for path in sorted(NOTEBOOKS.glob("[0-9][0-9]*_*.ipynb")):
        if path.stem > own:
            break
        for i, c in enumerate(_cells(path.stem)):
            text = "".join(c["source"])
            if path.stem == own and f'check("{name}"' in text:
                break
            if c["cell_type"] == "code":
                early += [f"{path.stem} cell {i}: {e}" for e in SHOWN_SOURCE.findall(text)
                          if _shows(e, names)]
    assert not early, f"{name}'s answer shown before its check: " + "; ".join(early)


def test_the_notebooks_readme_lists_every_exercise_with_its_notebook():
    text = (NOTEBOOKS / "README.md").read_text()
    rows = {name: number for number, name in re.findall(r"^\| (\d\d\w?) \| `(\w+)`", text, re.M)}
    assert rows == {name: ex.notebook.split("_")[0] for name, ex in EXERCISES.items()}
