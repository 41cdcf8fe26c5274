"""The results report: tables and figures of the experiments, from recorded trials."""

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.evaluation.experiments import ExperimentResult
from dgt_lib.evaluation.queries import Query
from dgt_lib.evaluation.trials import TrialResult, TrialTask
from dgt_lib.navigation.outcome import TrialOutcome
from dgt_lib.report import write_results


def test_report_has_every_table_and_its_figures(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke")
    results = []
    for v, ok in (("jeep", True), ("vw_van", False)):
        for m in ("dgt", "single-task"):
            task = TrialTask("experiment3", "eval", m, v, Query((0, 0, 0), (5, 5), "random"),
                             0, "smoke", 0)
            outcome = TrialOutcome(True, "success", 3.0) if ok else TrialOutcome.failure(
                "immobilized", 12.0)
            results.append(TrialResult(task, outcome))
    path = write_results([ExperimentResult("experiment3", "eval", results)], prof)
    text = path.read_text()
    assert "Experiment 3" in text and "| DGT-Map | 1 / 1 | 100.0 |" in text
    assert "| 70 | 70.0 |" in text  # the paper's jeep row beside ours
    assert (path.parent / "experiment3_success.png").stat().st_size > 1000
    assert "![experiment3_success](experiment3_success.png)" in text
