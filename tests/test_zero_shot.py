"""Zero-shot: each named vehicle left out of the conditioned network's training in turn,
its costmap predicted from its spec alone and scored against its ground truth beside the
maps it could otherwise get (its own head, the nearest seen vehicle's, Slope-Based from its
climb)."""

import importlib
import sys
from pathlib import Path

import numpy as np

from dgt_lib.core.config import VEHICLES
from dgt_lib.evaluation.ground_truth import GroundTruth
from tests import test_conditioned_stage as stage_tests
from tests.test_conditioned_stage import PROFILE

dataset, ramp_world = stage_tests.dataset, stage_tests.ramp_world  # the fixtures
STUDIES = str(Path(__file__).resolve().parents[1] / "studies")
if STUDIES not in sys.path:  # the study's scoring lives beside its script
    sys.path.append(STUDIES)
zero_shot = importlib.import_module("zero_shot_scores")
nearest_vehicle = zero_shot.nearest_vehicle


def _ground_truth(vehicle: str, bev) -> GroundTruth:
    k = PROFILE.costmap.n_headings
    cells = np.array([[6.2, 8.2], [10.2, 8.2], [12.2, 6.2]])
    headings = np.linspace(0.0, 2 * np.pi, k, endpoint=False)
    locomotion = np.tile(1.0 - 0.5 * (np.cos(headings) > 0.5), (3, 1))  # +x is uphill
    return GroundTruth("ramp", vehicle, cells, np.zeros(3, np.int64), headings, locomotion,
                       np.zeros((3, k), np.int8), np.full((3, k), 5.0), np.zeros((3, k)))


def test_zero_shot_scores_every_comparison_for_each_left_out_vehicle(ramp_world, dataset,
                                                                     monkeypatch):
    monkeypatch.setattr(zero_shot, "scored_worlds", lambda vehicle: ("ramp",))
    monkeypatch.setattr(zero_shot, "ensure_dataset", lambda prof, progress=True: dataset)
    monkeypatch.setattr(zero_shot, "ensure_ground_truths", lambda pairs, prof, progress=True:
                        {p: _ground_truth(p[1], ramp_world) for p in pairs})
    for vehicle in VEHICLES:
        result = zero_shot.zero_shot_scores(vehicle, PROFILE, plans=False, progress=False)
        methods = [r["method"] for r in result["rows"]]
        assert methods == list(zero_shot.ZERO_SHOT_METHODS)
        assert result["nearest"] == nearest_vehicle(vehicle, [v for v in VEHICLES
                                                              if v != vehicle])[0]
        assert result["nearest"] != vehicle
        assert (result["generated"], result["generated_used"]) == (0, 0)
        for row in result["rows"]:
            assert row["vehicle"] == vehicle and row["n"] > 0 and 0 <= row["mae"] <= 1
        n_test = int(((dataset.split == 2) & (dataset.vehicle == VEHICLES.index(vehicle))).sum())
        assert list(result["patches"]) == list(zero_shot.ZERO_SHOT_METHODS)
        assert all(m["n"] == n_test > 0 for m in result["patches"].values())
    zs = {r["method"]: r["mae"] for r in result["rows"]}
    assert zs["zero-shot"] != zs["own head"]  # two networks, two maps


def test_the_study_prints_its_tables_and_figure_from_stored_scores(tmp_path):
    """``studies/zero_shot.py --stored``: the tables over seeds and the figure from the
    stored scores alone, each left-out vehicle naming its nearest seen vehicle."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    scores = tmp_path / "scores"
    scores.mkdir()
    methods = zero_shot.ZERO_SHOT_METHODS
    for seed in (0, 1):
        rows = [{"world": "hill", "vehicle": "carla_cola", "method": m, "mae": 0.1 * (i + seed)}
                for i, m in enumerate(methods)]
        routes = {m: {"ascent": {"A": 1 + seed, "B": 9 - seed}, "descent": {"B": 10}}
                  for m in methods}
        patches = {m: {"n": 40, "mae": 0.2} for m in methods}
        (scores / f"seed{seed}_without_carla_cola.json").write_text(json.dumps(
            {"vehicle": "carla_cola", "seed": seed, "nearest": "mercedes_van", "rows": rows,
             "patches": patches, "plans": {"experiment1": routes}}))
    done = subprocess.run(
        [sys.executable, str(root / "studies" / "zero_shot.py"), "--profile", "smoke",
         "--seeds", "2", "--out", str(tmp_path), "--stored"],
        capture_output=True, text=True, cwd=root, timeout=300,
        env={**os.environ, "PYTHONPATH": str(root), "MPLBACKEND": "Agg"})
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert "| hill | carla_cola (nearest: mercedes_van) | 0, 1 | 0.050 ± 0.050 |" in out
    assert "| zero-shot | 1/10, 2/10 | 10/10, 10/10 | – |" in out
    assert "| carla_cola | 40, 40 | 0.200 ± 0.000 |" in out
    assert (tmp_path / "zero_shot.png").exists()


def test_the_study_s_record_names_its_tables_and_keeps_partial_runs_apart():
    """The record holds the tables ``mae``, ``ratio``, ``patches`` and ``plans``; one
    with generated vehicles or with only some left-out vehicles is a variant of its own."""
    study = importlib.import_module("zero_shot")
    methods = zero_shot.ZERO_SHOT_METHODS
    scores = [{"vehicle": v, "seed": 0, "nearest": "jeep", "plans": {},
               "rows": [{"world": "eval", "vehicle": v, "method": m, "mae": 0.1}
                        for m in methods]} for v in VEHICLES]
    tables = study.tables(scores)
    assert list(tables) == ["mae", "ratio", "patches", "plans"]
    assert tables["ratio"]["rows"][-1] == ["**vehicles within 25 %**", "", "4 of 4"]
    assert study.record_variant(scores, 0) == ""
    assert study.record_variant(scores, 8) == "gen8"
    assert study.record_variant(scores[::-1][:2], 0) == "without-mercedes_van-carla_cola"
    assert study.record_variant(scores[:1], 8) == "gen8-without-jeep"
