"""Conclusions over seeds (dgt_lib.evaluation.seeds): per seed, pooled, spread, claims."""

import pytest

from dgt_lib.evaluation.paper import PAPER
from dgt_lib.evaluation.seeds import (
    CLAIMS,
    claim_holds,
    claims_table,
    pooled_rows,
    pooled_table,
)
from dgt_lib.evaluation.statistics import wilson_interval


def test_pooled_rows_add_up_the_seeds_and_keep_their_spread():
    per_seed = [{"dgt": (6, 6), "binary": (0, 6)}, {"dgt": (3, 6), "binary": (1, 6)},
                {"dgt": (5, 6)}]
    rows = pooled_rows(per_seed)
    assert [r["method"] for r in rows] == ["dgt", "binary"]  # the paper's order
    dgt, binary = rows
    assert (dgt["k"], dgt["n"]) == (14, 18) and dgt["spread_pct"] == (50.0, 100.0)
    lo, hi = wilson_interval(14, 18)
    assert (dgt["ci_low_pct"], dgt["ci_high_pct"]) == (100 * lo, 100 * hi)
    assert binary["per_seed"] == [(0, 6), (1, 6), None] and (binary["k"], binary["n"]) == (1, 12)
    table = pooled_table(rows, [0, 1, 2], PAPER["experiment2"]["mercedes_van"])
    assert "| DGT-Map | 6/6 | 3/6 | 5/6 | 14 / 18 | 78 |" in table
    assert table.splitlines()[2].endswith("| 47/50 |")


def _summary(seed, ascents, crossings, collapsed=()):
    return {"seed": seed,
            "experiments": {"experiment1": {"routes": {"dgt": {"ascent": ascents}}},
                            "experiment2": {"routes": {"dgt": crossings}}},
            "models": {}, "collapsed": {"multitask": list(collapsed), "single:jeep": []}}


def test_a_claim_holds_in_a_seed_only_if_every_plan_makes_it():
    good = _summary(0, {"A": 3}, {"northbound": {"smooth": 3}, "southbound": {"smooth": 3}})
    bad = _summary(1, {"A": 2, "B": 1}, {"northbound": {"smooth": 3}, "southbound": {"sharp": 1,
                   "smooth": 2}}, collapsed=["jeep"])
    count = {name: fn for name, (_, fn) in CLAIMS.items()}
    assert count["hill_ascent_A"](good) == (3, 3) and count["hill_ascent_A"](bad) == (2, 3)
    assert count["ridge_smooth"](bad) == (5, 6)
    assert count["no_collapse"](good) == (0, 2) and count["no_collapse"](bad) == (1, 2)
    assert claim_holds("hill_ascent_A", 3, 3) and not claim_holds("hill_ascent_A", 2, 3)
    assert claim_holds("no_collapse", 0, 2) and not claim_holds("no_collapse", 1, 2)
    assert not claim_holds("ridge_smooth", 0, 0)  # nothing planned: nothing shown
    table = claims_table([good, bad])
    assert "| 3/3 ✓ | 2/3 ✗ | 1 of 2 seeds |" in table


@pytest.mark.parametrize("name", list(CLAIMS))
def test_every_claim_is_described(name):
    assert CLAIMS[name][0]
