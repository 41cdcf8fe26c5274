"""The results report: tables and figures of the experiments, from recorded trials."""

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.evaluation.experiments import ExperimentResult
from dgt_lib.evaluation.queries import Query
from dgt_lib.evaluation.trials import TrialResult, TrialTask
from dgt_lib.navigation.outcome import TrialOutcome
from dgt_lib.report import write_results


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


def test_a_report_made_with_changed_settings_says_which(tmp_path, monkeypatch):
    """`dgt reproduce --set planner.beta=50` writes where the profile's results go: the
    title says so, and so does the seed's summary that the pooled report reads."""
    import json

    from dgt_lib.report import SUMMARY_RELPATH, write_seed_summary
    from dgt_lib.stages.paths import data_dir

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    plain = write_results([_experiment3()], get_profile("smoke")).read_text()
    assert plain.splitlines()[0] == "# Results — profile `smoke`"
    prof = get_profile("smoke").with_overrides({"planner.beta": 50})
    text = write_results([_experiment3()], prof).read_text()
    assert text.splitlines()[0] == "# Results — profile `smoke` with planner.beta=50.0"
    write_seed_summary([_experiment3()], prof)
    summary = json.loads((data_dir(prof) / SUMMARY_RELPATH).read_text())
    assert summary["overrides"] == {"planner.beta": "50.0"}
