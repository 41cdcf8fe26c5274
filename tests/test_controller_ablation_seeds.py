"""``studies/controller_ablation.py``'s per-seed table: what a table pooled over the seeds hides."""

import importlib
import sys
from pathlib import Path
from types import SimpleNamespace

STUDIES = str(Path(__file__).resolve().parents[1] / "studies")
if STUDIES not in sys.path:  # the study's script and its helpers live there
    sys.path.append(STUDIES)
ablation = importlib.import_module("controller_ablation")


def _result(successes: dict[str, list[bool]]) -> SimpleNamespace:
    """One seed's experiment: the jeep's trials per method, arrived or not."""
    trials = [SimpleNamespace(task=SimpleNamespace(vehicle="jeep", method=m),
                              outcome=SimpleNamespace(success=ok))
              for m, oks in successes.items() for ok in oks]
    return SimpleNamespace(world="eval_hazard", results=trials)


def test_each_seed_keeps_its_own_count_where_the_pooled_table_adds_them():
    runs = {"paper": [(0, _result({"dgt": [True, True], "binary": [False, True]})),
                      (4, _result({"dgt": [True, False], "binary": [False, False]}))]}
    tab = ablation.by_seed("experiment3", runs)
    assert tab["columns"][3:] == ["seed 0", "seed 4"]
    rows = {row[1]: row[3:] for row in tab["rows"]}
    assert rows == {"DGT-Map": ["2/2", "1/2"], "Binary": ["1/2", "0/2"]}
