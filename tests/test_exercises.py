"""The notebooks' graded exercises: the grader accepts the library's own answer, catches
each common mistake with its hint, and tells an unanswered exercise apart from a wrong one."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy import stats

from dgt_lib import exercises
from dgt_lib.exercises import EXERCISES, NOT_ANSWERED, RIGHT, WRONG, check, grade


def _lstsq_plane(points):
    a = np.column_stack([np.ones(len(points)), points[:, :2]])
    return tuple(np.linalg.lstsq(a, points[:, 2], rcond=None)[0])


def _sq(x):
    return x * x


# A right answer written independently of the library, for each exercise.
LEARNER_RIGHT = {
    "cell_plane": _lstsq_plane,
    "locomotion": lambda d, dt: np.exp(-_sq((5.0 * dt - d) / (5.0 * dt)) * 4.5),
    "masked_loss": lambda p, y, h: ((p[torch.arange(len(h)), h] - y) ** 2).mean(),
    "heading_bin": lambda t, k: np.round(np.mod(t, 2 * np.pi) / (2 * np.pi / k)).astype(int) % k,
    "edge_cost": lambda s, c, b: s * (1 + c + b * c * c),
    "slope_locomotion": lambda t, t0, lo, hi, pu, pd: np.where(
        (t < lo) | (t > hi), 0.0,
        np.where(t >= t0, 1 - np.clip((t - t0) / (hi - t0), 0, 1) ** pu,
                 1 - np.clip((t0 - t) / (t0 - lo), 0, 1) ** pd)),
    "test_errors": lambda p, t: (np.mean((p - t) ** 2), np.mean(np.abs(p - t)),
                                 stats.spearmanr(p, t).statistic),
    "contrast_pairs": lambda c, v, th: np.nonzero(
        (np.abs(c[:, 4:] - c[:, :4]) > th) & v[:, 4:] & v[:, :4]),
    "trial_outcome": lambda d, imm, done, t, limit: (
        "success" if d <= 5.0 else "flipped" if done == "flipped" else "diverged" if done
        else "immobilized" if imm > 10.0 else "timeout" if t >= limit else "driving"),
    "mppi_weights": lambda s, lam: (lambda e: e / e.sum())(np.exp((s.min() - s) / lam)),
}

# One deliberate mistake per exercise, and the words its hint must contain.
LEARNER_WRONG = {
    "cell_plane": (lambda p: (p[:, 2].mean(), *_lstsq_plane(p)[1:]), "cell centre"),
    "locomotion": (lambda d, dt: np.exp(-_sq((5.0 - d) / 5.0) * 4.5), "divide by it"),
    "masked_loss": (lambda p, y, h: ((p - y[:, None]) ** 2).mean(), "only the head"),
    "heading_bin": (lambda t, k: (np.mod(t, 2 * np.pi) // (2 * np.pi / k)).astype(int) % k,
                    "nearest bin"),
    "edge_cost": (lambda s, c, b: s * (1 + c + b * c), "super-linear"),
    "slope_locomotion": (lambda t, t0, lo, hi, pu, pd: 1 - np.clip(
        np.abs(t - t0) / (hi - t0), 0, 1) ** pu, "downhill"),
    "test_errors": (lambda p, t: (np.mean((p - t) ** 2), np.mean(np.abs(p - t)),
                                  stats.pearsonr(p, t).statistic), "ranks"),
    "contrast_pairs": (lambda c, v, th: np.nonzero(
        np.abs(c[:, 4:] - c[:, :4]) > th), "both samples"),
    "trial_outcome": (lambda d, imm, done, t, limit: (
        "success" if d <= 5.0 else "flipped" if done else "immobilized" if imm >= 10.0
        else "timeout" if t >= limit else "driving"), "exactly 10 s"),
    "mppi_weights": (lambda s, lam: (lambda e: e / e.sum())(np.exp(-s / lam)), "min S"),
}


def _unanswered(*args):
    raise NotImplementedError


def test_every_notebook_has_an_exercise():
    notebooks = {ex.notebook[:2] for ex in EXERCISES.values()}
    assert notebooks == {f"{i:02d}" for i in range(1, 10)} | {"11"}
    assert set(LEARNER_RIGHT) == set(EXERCISES) == set(LEARNER_WRONG)


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_reference_passes_its_own_check(name):
    assert grade(name, EXERCISES[name].reference).status == RIGHT


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_an_independent_right_answer_passes(name):
    result = grade(name, LEARNER_RIGHT[name])
    assert result.status == RIGHT, result.message


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_a_wrong_answer_is_reported_with_its_hint(name):
    wrong, words = LEARNER_WRONG[name]
    result = grade(name, wrong)
    assert result.status == WRONG
    assert words in result.hint
    assert result.message.startswith("wrong: ")


@pytest.mark.parametrize("name", sorted(EXERCISES))
def test_an_unanswered_exercise_shows_the_reference_instead_of_failing(name):
    for learner in (_unanswered, lambda *args: None):
        result = grade(name, learner)
        assert result.status == NOT_ANSWERED
        assert result.message.startswith("not answered yet")
        assert "reference gives" in result.message


def test_check_prints_the_verdict(capsys):
    check("edge_cost", LEARNER_RIGHT["edge_cost"])
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
        return LEARNER_RIGHT["heading_bin"](theta, k)

    assert grade("heading_bin", partly).status == WRONG


def test_the_learner_cannot_change_the_inputs_the_reference_sees():
    def clobber(points):
        points[:, 2] = 0.0
        return exercises.EXERCISES["cell_plane"].reference(points)

    assert grade("cell_plane", clobber).status == WRONG


def test_an_unknown_exercise_names_the_known_ones():
    with pytest.raises(KeyError, match="locomotion"):
        grade("no_such_exercise", _unanswered)


NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"


def _exercise_cells(name):
    nb = json.loads((NOTEBOOKS / f"{EXERCISES[name].notebook}.ipynb").read_text())
    cells = {c.get("id"): "".join(c["source"]) for c in nb["cells"]}
    return [cells.get(f"exercise-{name}-{part}") for part in ("task", "answer", "check")]


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
