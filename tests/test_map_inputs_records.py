"""``studies/map_inputs.py``'s record: the input attribution's and the pose-noise study's
tables over seeds, from scores in the shape the study stores, each run a record of its own."""

import importlib
import json
import sys
from pathlib import Path

from dgt_lib.records import study as records

STUDIES = str(Path(__file__).resolve().parents[1] / "studies")
if STUDIES not in sys.path:  # the study's script and its helpers live there
    sys.path.append(STUDIES)
map_inputs = importlib.import_module("map_inputs")

PAIRS = [("hill", "carla_cola"), ("ridge", "mercedes_van"), ("ridge", "jeep"),
         ("eval", "jeep"), ("eval", "vw_van")]


def _scores(variant: str, seed: int, shift: float = 0.0) -> dict:
    """One (variant, seed)'s scores as ``score()`` returns them: pair i's MAE
    0.1·(i+1) + 0.01·seed + shift; seed k plans 10−k of 10 ascents by Route A, 9 of 10
    descents by Route B and 45+k of 50 ridge crossings at the smoothed section."""
    accuracy = [{"world": w, "vehicle": v, "mae": 0.1 * (i + 1) + 0.01 * seed + shift,
                 "spearman": 0.5, "contrast": 0.3} for i, (w, v) in enumerate(PAIRS)]
    plans = {"experiment1": {"ascent": {"A": 10 - seed, "B": seed},
                             "descent": {"B": 9, "other": 1}},
             "experiment2": {"northbound": {"smooth": 20 + seed, "sharp": 5 - seed},
                             "southbound": {"smooth": 25}}}
    costs = {v: {"sharp_crossing": 0.5 + 0.1 * seed, "smooth_crossing": 0.01 * seed}
             for v in ("jeep", "mercedes_van")}
    return {"variant": variant, "seed": seed, "settings": map_inputs.VARIANTS[variant],
            "accuracy": accuracy, "plans": plans, "ridge_costs": costs}


def _run(variants: list[str], seeds=(0, 2)) -> list[dict]:
    return [_scores(v, s, shift=0.1 * i) for i, v in enumerate(variants) for s in seeds]


def test_the_mae_table_gives_mean_and_std_over_seeds_per_pair_and_variant():
    tables = map_inputs.tables(_run(["rgbd", "shuffled", "geometry", "rgb"]))
    assert list(tables) == ["mae", "plans"]
    mae = tables["mae"]
    assert mae["columns"] == ["variant", "seeds", "hill carla_cola", "ridge mercedes_van",
                              "ridge jeep", "eval jeep", "eval vw_van", "mean"]
    assert mae["rows"][0] == ["rgbd (the paper)", "0, 2", "0.110 ± 0.010", "0.210 ± 0.010",
                              "0.310 ± 0.010", "0.410 ± 0.010", "0.510 ± 0.010", "0.310"]
    assert mae["rows"][1][:3] == ["shuffled colours", "0, 2", "0.210 ± 0.010"]
    assert mae["rows"][1][-1] == "0.410"
    assert [r[0] for r in mae["rows"]] == ["rgbd (the paper)", "shuffled colours",
                                           "geometry only", "RGB only"]


def test_the_plans_table_counts_each_claim_and_the_van_s_costs_per_seed():
    plans = map_inputs.tables(_run(["rgbd", "geometry"]))["plans"]
    assert plans["columns"] == ["variant", "hill ascents by Route A", "hill descents by Route B",
                                "ridge crossings at the smoothed section",
                                "van cost sharp / smooth (N)"]
    assert plans["rows"][0] == ["rgbd (the paper)", "10/10, 8/10", "9/10, 9/10",
                                "45/50, 47/50", "0.50 / 0.00, 0.70 / 0.02"]
    assert plans["rows"][1][0] == "geometry only"


def test_a_pose_run_names_its_rows_by_the_noise_and_the_paper_s_by_its_true_poses():
    tables = map_inputs.tables(_run(["rgbd", "pose_low", "pose_mid", "pose_high"], seeds=(0,)))
    labels = ["true poses (the paper)", "σ_xy 0.1 m, σ_ψ 0.5°, σ_d 0.01 m",
              "σ_xy 0.3 m, σ_ψ 2°, σ_d 0.02 m", "σ_xy 1.0 m, σ_ψ 2°, σ_d 0.05 m"]
    assert [r[0] for r in tables["mae"]["rows"]] == labels
    assert [r[0] for r in tables["plans"]["rows"]] == labels
    assert tables["mae"]["rows"][3][1:3] == ["0", "0.400 ± 0.000"]


def test_the_attribution_and_the_pose_run_are_records_of_their_own():
    variant = map_inputs.record_variant
    assert variant(_run(["rgbd", "shuffled", "geometry", "rgb"])) == "attribution"
    assert variant(_run(["rgbd", "geometry"])) == "rgbd-geometry"  # partial: its own record
    assert variant(_run(["rgbd", "pose_low", "pose_mid", "pose_high"])) == "pose"
    assert variant(_run(["pose_high"])) == "pose_high"
    assert variant(_run(["pose_low", "rgbd", "geometry"])) == "rgbd-geometry-pose_low"


def test_stored_scores_are_published_as_the_attribution_s_record(tmp_path, monkeypatch):
    """``--stored --publish``: the record from the stored scores alone, named by its
    variant, and the figure beside it."""
    scores = _run(["rgbd", "geometry", "rgb", "shuffled"])
    (tmp_path / "scores").mkdir()
    for s in scores:
        (tmp_path / "scores" / f"{s['variant']}_seed{s['seed']}.json").write_text(json.dumps(s))
    monkeypatch.setattr(records, "STUDIES", tmp_path / "records")
    monkeypatch.setattr(sys, "argv", [
        "map_inputs.py", "--seed", "0", "--seed", "2", "--variants", "rgbd", "geometry",
        "rgb", "shuffled", "--out", str(tmp_path), "--figure", str(tmp_path / "f.png"),
        "--stored", "--publish"])
    map_inputs.main()
    [path] = (tmp_path / "records").glob("*.json")
    assert path.name.startswith("map_inputs-attribution_demo_")
    record = json.loads(path.read_text())
    assert record["seeds"] == [0, 2] and record["variant"] == "attribution"
    assert record["tables"] == map_inputs.tables(scores)
    # the command reruns the study from nothing: no --stored
    assert record["command"].endswith(f"--out {tmp_path} --figure {tmp_path / 'f.png'} --publish")
    assert (tmp_path / "f.png").exists()
