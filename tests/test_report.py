"""The results report: tables and figures of the experiments, from recorded trials."""

from dgt_lib.app.report import write_results
from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.evaluation.experiments import ExperimentResult
from dgt_lib.evaluation.queries import Query
from dgt_lib.evaluation.trials import TrialResult, TrialTask
from dgt_lib.navigation.outcome import TrialOutcome


def _experiment3() -> ExperimentResult:
    """Experiment 3 with one trial per method and vehicle: the jeep's succeed."""
    results = []
    for v, ok in (("jeep", True), ("vw_van", False)):
        for m in ("dgt", "single-task"):
            task = TrialTask("experiment3", "eval", m, v, Query((0, 0, 0), (5, 5), "random"),
                             0, "smoke", 0)
            outcome = TrialOutcome(True, "success", 3.0) if ok else TrialOutcome.failure(
                "immobilized", 12.0)
            results.append(TrialResult(task, outcome))
    return ExperimentResult("experiment3", "eval", results)


def test_report_has_every_table_and_its_figures(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke")
    path = write_results([_experiment3()], prof)
    text = path.read_text()
    assert "Experiment 3" in text and "| DGT-Map | 1 / 1 | 100.0 |" in text
    assert "| 70 | 70.0 |" in text  # the paper's jeep row beside ours
    assert (path.parent / "experiment3_success.png").stat().st_size > 1000
    assert "![experiment3_success](experiment3_success.png)" in text
    assert "Not measured for this seed: run `dgt reproduce --stages ground_truth`" in text


def test_a_report_made_with_changed_settings_says_which_and_leaves_the_run_s_own(
        tmp_path, monkeypatch):
    """`dgt reproduce --set planner.beta=50` writes its report and run record beside the
    seed's own: the title and the record say which settings changed, and the profile's
    record (the one `records publish` copies) is still the plain run's."""
    import json

    from dgt_lib.records.record import SUMMARY_NAME, seed_summaries, write_seed_record
    from dgt_lib.stages.paths import results_dir

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    smoke = get_profile("smoke")
    plain_path = write_results([_experiment3()], smoke)
    write_seed_record([_experiment3()], smoke)
    plain = plain_path.read_text()
    assert plain.splitlines()[0] == "# Results — profile `smoke`"
    prof = smoke.with_overrides({"planner.beta": 50})
    variant_path = write_results([_experiment3()], prof)
    assert variant_path != plain_path and plain_path.read_text() == plain
    text = variant_path.read_text()
    assert text.splitlines()[0] == "# Results — profile `smoke` with planner.beta=50.0"
    write_seed_record([_experiment3()], prof)
    summary = json.loads((results_dir(prof) / SUMMARY_NAME).read_text())
    assert summary["overrides"] == {"planner.beta": "50.0"}
    assert [s["overrides"] for s in seed_summaries(smoke.with_(seeds=1))] == [{}]


def _accuracy_rows(mt_mae, st_mae):
    rows = []
    for world, vehicle in (("hill", "carla_cola"), ("ridge", "mercedes_van")):
        for method, mae in (("dgt", mt_mae), ("single-task", st_mae), ("binary", 0.5)):
            rows.append({"world": world, "vehicle": vehicle, "method": method, "n": 20,
                         "excluded": 0, "mae": mae, "spearman": 0.5, "pairs": 2,
                         "contrast_true": 0.8, "contrast": 0.4, "sign_agreement": 1.0})
    return rows


def _comparisons(closer):
    return [{"vehicle": "carla_cola", "worlds": ["hill"], "n": 20, "mae_a": 0.1, "mae_b": 0.2,
             "spearman_a": 0.5, "spearman_b": 0.4, "p": 0.01, "closer": closer},
            {"vehicle": "mercedes_van", "worlds": ["ridge"], "n": 20, "mae_a": 0.1,
             "mae_b": 0.2, "spearman_a": 0.5, "spearman_b": 0.4, "p": 0.01, "closer": closer}]


def test_report_prints_the_accuracy_tables_and_draws_the_ground_truth(tmp_path, monkeypatch):
    import numpy as np

    from dgt_lib.app import report
    from dgt_lib.evaluation.ground_truth import GroundTruth
    from dgt_lib.mapping.world_maps import WorldMaps
    from dgt_lib.perception.bev import BEVMap
    from dgt_lib.stages.ground_truth import ACCURACY_RELPATH
    from dgt_lib.stages.paths import data_dir
    from dgt_lib.world.terrain import get_world

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke")
    artifacts.save(data_dir(prof) / ACCURACY_RELPATH,
                   {"rows": _accuracy_rows(0.1, 0.2), "multitask": _comparisons("multi-task"),
                    "ground_truth": {"hill/carla_cola": "x"}})

    def truth(world, vehicle, profile, progress=True):
        k, cells = 8, np.array([[30.0, 50.0], [60.0, 30.0]])
        return GroundTruth(world, vehicle, cells, np.zeros(2, np.int64), np.zeros(k),
                           np.full((2, k), 0.5), np.zeros((2, k), np.int8),
                           np.full((2, k), 5.0), np.zeros((2, k)))

    def maps(world, vehicles, profile, progress=True):
        grid = get_world(world, profile).grid
        bev = BEVMap(grid, np.zeros((6, *grid.shape), np.float32), np.ones(grid.shape, bool),
                     np.ones(grid.shape, np.int64))
        layers = np.zeros((8, *grid.shape), np.float32)
        return WorldMaps(world, bev, np.zeros(grid.shape, np.uint8), 0.6,
                         {(m, v): layers for m in ("dgt", "single-task", "slope")
                          for v in vehicles})

    monkeypatch.setattr(report, "ensure_ground_truth", truth)
    monkeypatch.setattr(report, "ensure_world_costmaps", maps)
    text = write_results([], prof).read_text()
    assert "## Costmap accuracy against the measured ground truth" in text
    assert "| carla_cola | hill | 20 | 0.100 | 0.200 | 0.50 | 0.40 | 0.010 | multi-task |" in text
    assert "| hill | carla_cola | Binary | 20 | 0.500 |" in text
    for world in ("hill", "ridge"):
        assert f"![accuracy_{world}](accuracy_{world}.png)" in text
        assert (data_dir(prof) / "results" / f"accuracy_{world}.png").stat().st_size > 1000


def test_the_seeds_report_pools_the_accuracy_and_checks_claim_4_per_seed(tmp_path,
                                                                          monkeypatch):
    import json

    from dgt_lib.app.report import write_seeds_report
    from dgt_lib.records.record import SUMMARY_NAME
    from dgt_lib.stages.paths import results_dir

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke").with_(seeds=2)
    for p, (mt, st, closer) in zip(prof.seed_profiles(), ((0.1, 0.2, "multi-task"),
                                                          (0.3, 0.2, "neither")), strict=True):
        path = results_dir(p) / SUMMARY_NAME
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps({"seed": p.seed, "experiments": {}, "models": {},
                                    "collapsed": {}, "accuracy": _accuracy_rows(mt, st),
                                    "multitask": _comparisons(closer)}))
    text = write_seeds_report(prof).read_text()
    assert "| 2/2 ✓ | 0/2 ✗ | 1 of 2 seeds |" in text  # multi-task closer, seed by seed
    assert ("| carla_cola | 0.100 / 0.200 (multi-task) | 0.100 / 0.200 (neither) | "
            "1 of 2 seeds |") in text
    assert "| hill | carla_cola | DGT-Map | 0.100 / 0.50 | 0.300 / 0.50 | 0.200 | 0.50 |" in text
