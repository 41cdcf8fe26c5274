"""Graded exercises for the notebooks: write a function from the paper, check it here.

Each notebook has at least one exercise: a markdown cell states the task and its equation,
a code cell holds the learner's function (shipped unanswered: it raises
``NotImplementedError``) and a check cell calls :func:`check`. The hidden reference is the
library's own function (never a copy of it): :func:`grade` calls the learner's function and
the reference on a few inputs, each chosen to expose one common mistake, and reports

* ``right`` — every input agrees;
* ``wrong: <hint>`` — the first input that disagrees, its hint, and both values;
* ``not answered yet`` — the function raises ``NotImplementedError`` or returns ``None``;
  the message then shows what the reference gives on the first input, so a notebook run
  top to bottom (as under nbmake in CI) still prints a result and never fails.

As in the exercises of Tedrake's *Robotic Manipulation* course, the grader is a small
library module with tests of its own (``tests/test_exercises.py``)::

    from dgt_lib.exercises import check

    def locomotion_label(displacement_m, dt_s):
        ...  # the learner's code
    check("locomotion", locomotion_label)
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from dgt_lib.exercises.bank import EXERCISES, Case, Exercise

__all__ = ["EXERCISES", "Case", "CheckResult", "Exercise", "check", "grade", "plug"]

RIGHT, WRONG, NOT_ANSWERED = "right", "wrong", "not answered"


@dataclass(frozen=True)
class CheckResult:
    """What :func:`grade` found: ``status`` is ``right``, ``wrong`` or ``not answered``;
    ``message`` is the line :func:`check` prints; ``hint`` the failing case's hint."""

    name: str
    status: str
    message: str
    hint: str = ""

    @property
    def passed(self) -> bool:
        return self.status == RIGHT


# ----------------------------------------------------------------------------- grading
def _as_numbers(x: Any) -> Any:
    """Tensors → numpy, tuples/lists → tuples of the same, anything else → a float array."""
    if isinstance(x, (tuple, list)):
        return tuple(_as_numbers(v) for v in x)
    if hasattr(x, "detach"):  # a torch tensor
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=np.float64)


def _agree(got: Any, want: Any, atol: float) -> bool:
    if isinstance(want, tuple):
        return (isinstance(got, tuple) and len(got) == len(want)
                and all(_agree(g, w, atol) for g, w in zip(got, want, strict=True)))
    if isinstance(got, tuple) or got.shape != want.shape:
        return False
    return bool(np.allclose(got, want, rtol=1e-6, atol=atol, equal_nan=True))


def _show(x: Any) -> str:
    """A short printout of an argument or answer."""
    if isinstance(x, (tuple, list)):
        return "(" + ", ".join(_show(v) for v in x) + ")"
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, np.ndarray):
        return np.array2string(x, precision=4, threshold=12, edgeitems=2,
                               separator=", ").replace("\n", "")
    if isinstance(x, float) and not math.isnan(x):
        return f"{x:.6g}"
    return repr(x)


def _call(fn: Callable[..., Any], args: tuple) -> Any:
    return fn(*copy.deepcopy(args))  # the learner's function must not change the inputs


def grade(name: str, learner_fn: Callable[..., Any]) -> CheckResult:
    """Compare ``learner_fn`` with exercise ``name``'s reference on every case.

    Returns a :class:`CheckResult`; never raises because of the learner's code (an
    exception it raises, other than ``NotImplementedError``, is reported as wrong).
    """
    if name not in EXERCISES:
        raise KeyError(f"no exercise {name!r}; known: {', '.join(EXERCISES)}")
    ex = EXERCISES[name]
    cases = ex.cases()
    norm = ex.normalize or (lambda a: a)
    for i, case in enumerate(cases):
        want = _call(ex.reference, case.args)
        try:
            got = _call(learner_fn, case.args)
        except NotImplementedError:
            got = None
        except Exception as err:  # noqa: BLE001 — any error in the learner's code is a wrong answer
            msg = (f"wrong: {case.hint}\n  your function raised {type(err).__name__}: {err}\n"
                   f"  on input {_show(case.args)}")
            return CheckResult(name, WRONG, msg, case.hint)
        if got is None:
            if i == 0:
                msg = (f"not answered yet — write the body of `{learner_fn.__name__}` and rerun "
                       f"this cell.\n  Here is what the reference gives: "
                       f"{name}{_show(case.args)} = {_show(want)}")
                return CheckResult(name, NOT_ANSWERED, msg)
            msg = f"wrong: {case.hint}\n  your function returned None on input {_show(case.args)}"
            return CheckResult(name, WRONG, msg, case.hint)
        try:
            ok = _agree(_as_numbers(norm(got)), _as_numbers(norm(want)), ex.atol)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            msg = (f"wrong: {case.hint}\n  input {_show(case.args)}\n  yours     {_show(got)}\n"
                   f"  expected  {_show(want)}")
            return CheckResult(name, WRONG, msg, case.hint)
    return CheckResult(name, RIGHT, f"right — {name} agrees with dgt_lib on all "
                                    f"{len(cases)} inputs")


def check(name: str, learner_fn: Callable[..., Any]) -> None:
    """Grade ``learner_fn`` against exercise ``name`` and print the verdict (``right``,
    ``wrong: <hint>`` or ``not answered yet``) — the notebooks' check cells."""
    print(grade(name, learner_fn).message)


def plug(name: str, learner_fn: Callable[..., Any]) -> Callable[..., Any]:
    """The function the pipeline cells after an exercise run: the learner's own once it
    answers (right or not — a wrong one shows what it changes downstream), the library's
    reference while it is unanswered, so a notebook run top to bottom still works.

    Prints one line saying which is used and the grade, e.g.
    ``edge_cost: your function (right) drives the cells below``.
    """
    result = grade(name, learner_fn)
    if result.status == NOT_ANSWERED:
        print(f"{name}: not answered yet — the cells below use the library's reference")
        return EXERCISES[name].reference
    print(f"{name}: your function ({result.status}) drives the cells below")
    return learner_fn
