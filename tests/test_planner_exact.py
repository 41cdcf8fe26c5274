"""The exact planner's costs do not move: recorded from the pure-Python search at commit
3adf92a (before the planner was made faster) on the deterministic queries of
``tests/planner_cases.py``, and checked for every search backend.

Hybrid A*'s closed set keeps the first node expanded in each (x, y, θ) cell, so a search
that pops nodes in another order may return another (slightly costlier or cheaper) path:
the cost is exact only up to that discretisation. A faster search that pops the same nodes
in the same order returns the same cost to rounding, which is what is asserted: the
recorded cost to 1e-9, relative. A heuristic that overestimates, a wrong edge cost, a
missed collision or a changed closed-set rule moves some of these costs far more.
"""

import math

import pytest

from dgt_lib.navigation.planner import HybridAStar
from tests import planner_cases

RECORDED = {  # name: (cost, expansions) of the pure-Python search at commit 3adf92a
    "hill-up-cost_to_go": (79.09468236695092, 3092),
    "hill-down-cost_to_go": (49.968000000000025, 435),
    "hill-up-euclidean": (79.56400517657829, 6749),
    "hill-down-euclidean": (49.968000000000025, 749),
    "hill-up-isotropic": (79.09468236695092, 3092),
    "hill-up-noshot": (79.344, 3238),
    "field-0": (125.66461791217671, 362),
    "field-1": (235.8881376462216, 6606),
    "field-2": (228.09691041358047, 2768),
    "field-3": (186.4613357809515, 1730),
    "field-4": (105.82731680001736, 773),
    "field-5": (140.19387993435078, 1097),
    "field-6": (136.60338543726445, 528),
    "field-7": (354.1924583124266, 12456),
    "field-0-euclidean": (125.66461791217671, 471),
    "box-main": (123.91569911277193, 15182),
}

CASES = planner_cases.cases()


@pytest.fixture(scope="module")
def maps():
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = planner_cases.maps(name)
        return cache[name]

    return get


def test_every_case_is_recorded():
    assert sorted(name for name, *_ in CASES) == sorted(RECORDED)


@pytest.mark.parametrize("backend", ["python"])
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_exact_cost_is_the_recorded_one(maps, case, backend):
    name, map_name, vehicle, cfg, start, goal = case
    planner = HybridAStar(*maps(map_name), cfg=cfg, backend=backend, **vehicle)
    result = planner.plan(start, goal)
    cost, _ = RECORDED[name]
    assert result.success and math.isfinite(result.cost)
    assert result.cost == pytest.approx(cost, rel=1e-9, abs=0.0)
    assert result.node_costs[-1] == result.cost
